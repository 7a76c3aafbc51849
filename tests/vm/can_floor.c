/* The floor of the SocketCAN path oegw run translates on (vm_latency): a minimal
 * blocking forwarder. It reads one frame from IN_IF (only CAN-ID ID, filtered by the kernel) and
 * writes it unchanged to OUT_IF, nothing else: one read and one write per frame, no event loop,
 * no clock, no translation. Whatever a translator does on top of this is its own cost.
 *
 * With `loop` it forwards the way an event loop must instead (oegw's system path, without its
 * work): epoll_wait, one clock reading, every pending frame in one recvmmsg with
 * its kernel timestamp, all of them out in one sendmmsg. The difference between the two is what
 * the event loop's system calls cost; what `oegw run` adds on top of `loop` is its own work.
 *
 * Usage: can_floor IN_IF OUT_IF ID [loop]     e.g. can_floor vcan1 vcan0 0x191
 * Runs until a signal ends it; exits 1 if a socket cannot be set up or a read/write fails. */
#define _GNU_SOURCE
#include <linux/can.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <time.h>
#include <unistd.h>

#include "can_open.h"

enum { kBatch = 64 };

static int forward_loop(int in, int out) {
  int ep = epoll_create1(0);
  struct epoll_event ev = {.events = EPOLLIN, .data.fd = in};
  if (ep < 0 || epoll_ctl(ep, EPOLL_CTL_ADD, in, &ev) < 0) {
    perror("can_floor: epoll");
    return 1;
  }
  static struct can_frame frames[kBatch];
  static struct iovec iov[kBatch];
  static struct mmsghdr msgs[kBatch];
  static char control[kBatch][CMSG_SPACE(sizeof(struct timespec))];
  for (;;) {
    struct epoll_event events[8];
    if (epoll_wait(ep, events, 8, -1) < 0) continue;
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    for (int i = 0; i < kBatch; ++i) {
      iov[i] = (struct iovec){.iov_base = &frames[i], .iov_len = sizeof frames[i]};
      memset(&msgs[i], 0, sizeof msgs[i]);
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
      msgs[i].msg_hdr.msg_control = control[i];
      msgs[i].msg_hdr.msg_controllen = sizeof control[i];
    }
    int n = recvmmsg(in, msgs, kBatch, MSG_DONTWAIT, NULL);
    if (n <= 0) continue;
    for (int i = 0; i < n; ++i) { /* the same frames out: only the message headers differ */
      memset(&msgs[i].msg_hdr, 0, sizeof msgs[i].msg_hdr);
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    if (sendmmsg(out, msgs, (unsigned)n, 0) != n) {
      perror("can_floor: sendmmsg");
      return 1;
    }
  }
}

int main(int argc, char** argv) {
  int loop = argc == 5 && strcmp(argv[4], "loop") == 0;
  if (argc != 4 && !loop) {
    fprintf(stderr, "usage: %s IN_IF OUT_IF ID [loop]\n", argv[0]);
    return 2;
  }
  int in = open_can(argv[1], (canid_t)strtoul(argv[3], NULL, 0), 1, 0, loop);
  int out = open_can(argv[2], 0, 0, 0, 0); /* no filter: it receives nothing */
  if (in < 0 || out < 0) {
    perror("can_floor: socket");
    return 1;
  }
  if (loop) return forward_loop(in, out);
  struct can_frame frame;
  for (;;) {
    ssize_t n = read(in, &frame, sizeof frame);
    if (n != (ssize_t)sizeof frame || write(out, &frame, sizeof frame) != (ssize_t)sizeof frame) {
      perror("can_floor: read/write");
      return 1;
    }
  }
}
