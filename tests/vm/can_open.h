/* One raw CAN socket for the VM tier's C programs (can_floor.c, can_probe.c). */
#pragma once
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <string.h>
#include <sys/socket.h>

/* A CAN_RAW socket bound to `ifname` that receives the frames with CAN-ID `id` (standard and
 * extended alike) when `filtered`, none otherwise; `own`: its own frames too
 * (CAN_RAW_RECV_OWN_MSGS); `stamps`: kernel receive timestamps (SO_TIMESTAMPNS). -1 on error. */
static inline int open_can(const char* ifname, canid_t id, int filtered, int own, int stamps) {
  int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (s < 0) return -1;
  struct can_filter f = {.can_id = id, .can_mask = CAN_SFF_MASK | CAN_EFF_FLAG};
  if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, filtered ? &f : NULL, filtered ? sizeof f : 0) < 0) return -1;
  if (own && setsockopt(s, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof own) < 0) return -1;
  if (stamps && setsockopt(s, SOL_SOCKET, SO_TIMESTAMPNS, &stamps, sizeof stamps) < 0) return -1;
  struct sockaddr_can addr;
  memset(&addr, 0, sizeof addr);
  addr.can_family = AF_CAN;
  addr.can_ifindex = (int)if_nametoindex(ifname);
  if (addr.can_ifindex == 0 || bind(s, (struct sockaddr*)&addr, sizeof addr) < 0) return -1;
  return s;
}
