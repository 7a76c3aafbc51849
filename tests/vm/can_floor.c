/* The floor of the SocketCAN path oegw run translates on (issue 17 item 2, vm_latency): a minimal
 * blocking forwarder. It reads one frame from IN_IF (only CAN-ID ID, filtered by the kernel) and
 * writes it unchanged to OUT_IF, nothing else: one read and one write per frame, no event loop,
 * no clock, no translation. Whatever a translator does on top of this is its own cost.
 *
 * Usage: can_floor IN_IF OUT_IF ID      e.g. can_floor vcan1 vcan0 0x191
 * Runs until a signal ends it; exits 1 if a socket cannot be set up or a read/write fails. */
#include <linux/can.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "can_open.h"

int main(int argc, char** argv) {
  if (argc != 4) {
    fprintf(stderr, "usage: %s IN_IF OUT_IF ID\n", argv[0]);
    return 2;
  }
  int in = open_can(argv[1], (canid_t)strtoul(argv[3], NULL, 0), 1, 0, 0);
  int out = open_can(argv[2], 0, 0, 0, 0); /* no filter: it receives nothing */
  if (in < 0 || out < 0) {
    perror("can_floor: socket");
    return 1;
  }
  struct can_frame frame;
  for (;;) {
    ssize_t n = read(in, &frame, sizeof frame);
    if (n != (ssize_t)sizeof frame || write(out, &frame, sizeof frame) != (ssize_t)sizeof frame) {
      perror("can_floor: read/write");
      return 1;
    }
  }
}
