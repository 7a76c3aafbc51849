/* The measurer of vm_latency, the same for every translator it measures.
 *
 * can_probe latency IN_IF IN_ID OUT_IF OUT_ID EXPECT SAMPLES LOG [GAP_US] [WARMUP_S]
 *   Ping-pong: sends a frame with CAN-ID IN_ID on IN_IF (the grip's TPDO #0 as an elobau grip
 *   sends it: byte 0 = x in percent, the rest 0; x alternates between 0 and 10..99 %, so each
 *   frame changes what a translator sends), then waits up to 200 ms for its translation: the
 *   next frame with CAN-ID OUT_ID on OUT_IF that EXPECT says is the answer to this x ("copy": the
 *   same 8 bytes; "cia852": CiA 852 TPDO 1, joystick x INTEGER16 in bytes 0-1 = x at 100 % =
 *   32767, 0 inside the 2 % deadband), so a late answer to an earlier frame is never taken for
 *   this one's. The latency is the difference of the two frames' kernel timestamps
 *   (SO_TIMESTAMPNS; vcan stamps a frame when it is sent, so both are times on the wire and the
 *   probe's own scheduling does not count): its own frame read back (CAN_RAW_RECV_OWN_MSGS) and
 *   the answer. Then a pause of GAP_US (default 2000) plus a random 0..GAP_US. A frame goes out
 *   at least every 200 ms even while nothing answers, so a gateway's 300 ms PDO deadline never
 *   fires because of the probe. Before measuring it sends a frame every 50 ms until five in a row
 *   are answered (WARMUP_S, default 30: the translator boots its device, the gateway's neutral
 *   interlock waits for x = 0). LOG gets one line per sample: "IN_DATA OUT_DATA LATENCY_US" (hex
 *   data; "- miss" when unanswered; after 25 misses in a row, 5 s, it stops early).
 *   stdout: "samples N answered A missed M median_us X p99_us Y ...".
 *   Exit 0; 3 if nothing was answered (warm-up or measurement); 1 on a socket error.
 *
 * can_probe paths SAMPLES GAP_US WARMUP_S LOG_PREFIX NAME:IN_IF:IN_ID:OUT_IF:OUT_ID:EXPECT ...
 *   The same for up to 16 paths at once, each on its own interfaces, measured in turn: each cycle
 *   takes one sample of every path in a fresh random order (seeded: the same order every run),
 *   with the pause after each sample. So a swing of the machine's own timing — a TCG guest slows
 *   down by half whenever its host is busy — falls on every path alike rather than on whichever
 *   was being measured at the time, and the ratios between them stay steady. Warm-up path by
 *   path first (the last first); a path with 25 misses in a row is left out of the cycles that
 *   follow, and the exit is 3. Each path's
 *   samples go to LOG_PREFIX.NAME; stdout: one line per path, "NAME samples N ...".
 *
 * can_probe pace IF ID RATE SECONDS
 *   Sends RATE frames/s with CAN-ID ID on IF for SECONDS (the same alternating x), on an absolute
 *   schedule: each wake-up sends every frame due by then (at most 256) in one sendmmsg, so a late
 *   wake-up catches up and the sender's own system calls stay few.
 *   stdout: "sent N in S s: R frames/s, B send errors (ENOBUFS)". Exit 0; 1 on a socket error.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <math.h>
#include <net/if.h>
#include <poll.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "can_open.h"

static int64_t mono_ns(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

/* The i-th stimulus: x alternates 0 and 10..99 %. */
static struct can_frame stimulus(canid_t id, unsigned i) {
  struct can_frame f;
  memset(&f, 0, sizeof f);
  f.can_id = id;
  f.can_dlc = 8;
  f.data[0] = (i & 1) ? (uint8_t)(10 + (i / 2) % 90) : 0;
  return f;
}

/* One frame with its kernel timestamp (ns, CLOCK_REALTIME); flags = msg_flags. Waits up to
 * timeout_ms; 1 = got one, 0 = timeout, -1 = error. */
static int recv_stamped(int s, struct can_frame* f, int64_t* stamp, int* flags, int timeout_ms) {
  struct pollfd p = {.fd = s, .events = POLLIN};
  int r = poll(&p, 1, timeout_ms);
  if (r <= 0) return r;
  char ctrl[CMSG_SPACE(sizeof(struct timespec))];
  struct iovec iov = {.iov_base = f, .iov_len = sizeof *f};
  struct msghdr m = {.msg_iov = &iov, .msg_iovlen = 1, .msg_control = ctrl, .msg_controllen = sizeof ctrl};
  if (recvmsg(s, &m, 0) != (ssize_t)sizeof *f) return -1;
  *stamp = 0;
  for (struct cmsghdr* c = CMSG_FIRSTHDR(&m); c; c = CMSG_NXTHDR(&m, c))
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
      struct timespec t;
      memcpy(&t, CMSG_DATA(c), sizeof t);
      *stamp = (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
    }
  *flags = m.msg_flags;
  return 1;
}

static void hex(const struct can_frame* f, char* out) {
  for (int i = 0; i < f->can_dlc; ++i) sprintf(out + 2 * i, "%02X", f->data[i]);
  if (f->can_dlc == 0) strcpy(out, "-");
}

static int cmp_double(const void* a, const void* b) {
  double x = *(const double*)a, y = *(const double*)b;
  return (x > y) - (x < y);
}

/* Whether `f` is the translation of stimulus `x` (EXPECT: 'c' copy, 'n' cia852). */
static int is_answer(const struct can_frame* f, const struct can_frame* sent, char expect) {
  if (expect == 'c') return f->can_dlc == 8 && memcmp(f->data, sent->data, 8) == 0;
  int x = (int8_t)sent->data[0];
  const double scale = 32767.0 / 100.0; /* as mapping/translate.cpp: llround(v * scale) */
  long want = (x >= -2 && x <= 2) ? 0 : lround(x * scale);
  if (want > 32767) want = 32767;
  if (want < -32767) want = -32767;
  return f->can_dlc == 8 && (int16_t)(f->data[0] | (f->data[1] << 8)) == want;
}

/* Waits for the answer to `sent`; its frame in *got. */
static int wait_answer(int rx, const struct can_frame* sent, char expect, struct can_frame* got, int64_t* stamp,
                       int timeout_ms) {
  int64_t end = mono_ns() + (int64_t)timeout_ms * 1000000;
  for (;;) {
    int left = (int)((end - mono_ns()) / 1000000);
    if (left < 0) return 0;
    int flags;
    int r = recv_stamped(rx, got, stamp, &flags, left);
    if (r <= 0) return r;
    if (is_answer(got, sent, expect)) return 1;
  }
}

/* Sends the stimulus and reads it back: its stamp. */
static int send_stimulus(int tx, canid_t id, unsigned i, int64_t* stamp) {
  struct can_frame f = stimulus(id, i), back;
  if (write(tx, &f, sizeof f) != (ssize_t)sizeof f) return -1;
  for (;;) {
    int flags;
    int r = recv_stamped(tx, &back, stamp, &flags, 1000);
    if (r <= 0) return -1;
    if ((flags & MSG_CONFIRM) && back.can_id == f.can_id && memcmp(back.data, f.data, 8) == 0) return 0;
  }
}

/* One measured path: where its stimulus goes, where its translation comes from, what it got. */
struct path {
  char name[32];
  canid_t in_id, out_id;
  char expect;
  int tx, rx;
  unsigned i; /* its stimulus count: each path sees its own alternating x */
  FILE* log;
  double* lat;
  int answered, missed, misses_in_a_row;
};

/* "NAME:IN_IF:IN_ID:OUT_IF:OUT_ID:EXPECT" -> *p, its sockets open and its samples' log `log_file`
 * ("PREFIX.NAME" when log_file is a prefix, `log_is_prefix`). 0 = ok, 2 = bad spec, 1 = error. */
static int open_path(struct path* p, const char* spec, const char* log_file, int log_is_prefix, int samples) {
  char in_if[IFNAMSIZ], out_if[IFNAMSIZ], expect[8];
  unsigned in_id, out_id;
  memset(p, 0, sizeof *p);
  if (sscanf(spec, "%31[^:]:%15[^:]:%i:%15[^:]:%i:%7s", p->name, in_if, (int*)&in_id, out_if, (int*)&out_id, expect) !=
      6)
    return 2;
  p->in_id = in_id;
  p->out_id = out_id;
  p->expect = strcmp(expect, "copy") == 0 ? 'c' : strcmp(expect, "cia852") == 0 ? 'n' : 0;
  if (!p->expect) return 2;
  char file[512];
  if (log_is_prefix) snprintf(file, sizeof file, "%s.%s", log_file, p->name);
  else snprintf(file, sizeof file, "%s", log_file);
  p->log = fopen(file, "w");
  p->lat = calloc((size_t)samples, sizeof *p->lat);
  p->tx = open_can(in_if, in_id, 1, 1, 1);
  p->rx = open_can(out_if, out_id, 1, 0, 1);
  return p->log && p->lat && p->tx >= 0 && p->rx >= 0 ? 0 : 1;
}

/* Until five answers in a row (a frame every 50 ms), at most warmup_s. 0 = warm, 3 = none, 1 = error. */
static int warm_up(struct path* p, int warmup_s) {
  int64_t end = mono_ns() + (int64_t)warmup_s * 1000000000, t_in, t_out;
  struct can_frame got;
  for (int run = 0; run < 5;) {
    if (mono_ns() > end) return 3;
    struct can_frame sent = stimulus(p->in_id, p->i);
    if (send_stimulus(p->tx, p->in_id, p->i++, &t_in) < 0) return 1;
    run = wait_answer(p->rx, &sent, p->expect, &got, &t_out, 50) == 1 ? run + 1 : 0;
  }
  return 0;
}

/* One sample of p: the stimulus and its answer's latency. 0 = answered, 3 = missed, 1 = error. */
static int sample(struct path* p) {
  int64_t t_in, t_out;
  struct can_frame got, sent = stimulus(p->in_id, p->i);
  if (send_stimulus(p->tx, p->in_id, p->i++, &t_in) < 0) return 1;
  char in_hex[17], out_hex[17];
  hex(&sent, in_hex);
  if (wait_answer(p->rx, &sent, p->expect, &got, &t_out, 200) != 1) {
    fprintf(p->log, "%s - miss\n", in_hex);
    ++p->missed;
    ++p->misses_in_a_row;
    return 3;
  }
  p->lat[p->answered] = (double)(t_out - t_in) / 1000.0;
  hex(&got, out_hex);
  fprintf(p->log, "%s %s %.1f\n", in_hex, out_hex, p->lat[p->answered]);
  ++p->answered;
  p->misses_in_a_row = 0;
  return 0;
}

static void report_path(struct path* p, int samples) {
  if (strcmp(p->name, "-") != 0) printf("%s ", p->name); /* `paths`: which one */
  if (p->answered == 0) {
    printf("samples %d answered 0 missed %d\n", samples, p->missed);
    return;
  }
  qsort(p->lat, (size_t)p->answered, sizeof *p->lat, cmp_double);
  /* Nearest rank. */
  int p50 = (p->answered * 50 + 99) / 100 - 1, p99 = (p->answered * 99 + 99) / 100 - 1;
  printf("samples %d answered %d missed %d%s median_us %.1f p99_us %.1f min_us %.1f max_us %.1f\n", samples,
         p->answered, p->missed, p->misses_in_a_row >= 25 ? " (stopped: 25 misses in a row)" : "", p->lat[p50],
         p->lat[p99], p->lat[0], p->lat[p->answered - 1]);
}

/* The paths measured sample by sample in turn (a fresh random order each cycle), so whatever the
 * machine does meanwhile — a host's load on a TCG guest swings its timing between seconds — falls
 * on every path alike instead of on whichever was measured then. */
static int measure(struct path* paths, int n, int samples, long gap_us, int warmup_s) {
  /* Last path first: the first (vm_latency's gateway, whose PDO deadline is 300 ms) then starts
   * measuring right after its own warm-up rather than idling through the others'. */
  for (int k = n - 1; k >= 0; --k) {
    int r = warm_up(&paths[k], warmup_s);
    if (r == 1) return 1;
    if (r == 3) {
      printf("%s samples 0 answered 0 missed 0: no answer on 0x%X within %d s of warm-up\n", paths[k].name,
             paths[k].out_id, warmup_s);
      return 3;
    }
  }
  srand(1);
  int order[16];
  for (int cycle = 0; cycle < samples; ++cycle) {
    for (int k = 0; k < n; ++k) order[k] = k;
    for (int k = n - 1; k > 0; --k) { /* Fisher-Yates */
      int j = rand() % (k + 1), t = order[k];
      order[k] = order[j];
      order[j] = t;
    }
    for (int k = 0; k < n; ++k) {
      struct path* p = &paths[order[k]];
      if (p->misses_in_a_row >= 25) continue; /* 5 s without an answer: stopped */
      int r = sample(p);
      if (r == 1) return 1;
      if (r == 3) continue; /* at once: the next frame within the 300 ms a gateway allows between PDOs */
      long pause = gap_us + (gap_us > 0 ? rand() % gap_us : 0);
      struct timespec ts = {.tv_sec = pause / 1000000, .tv_nsec = (pause % 1000000) * 1000};
      nanosleep(&ts, NULL);
    }
  }
  int rc = 0;
  for (int k = 0; k < n; ++k) {
    fclose(paths[k].log);
    report_path(&paths[k], samples);
    if (paths[k].answered == 0 || paths[k].misses_in_a_row >= 25) rc = 3; /* silent, or stopped */
  }
  return rc;
}

static int latency(int argc, char** argv) {
  if (argc < 9) return 2;
  char spec[256];
  snprintf(spec, sizeof spec, "-:%s:%s:%s:%s:%s", argv[2], argv[3], argv[4], argv[5], argv[6]);
  int samples = atoi(argv[7]);
  struct path p;
  int r = samples > 0 ? open_path(&p, spec, argv[8], 0, samples) : 2;
  if (r == 2) return 2;
  if (r != 0) {
    perror("can_probe: setup");
    return 1;
  }
  return measure(&p, 1, samples, argc > 9 ? atol(argv[9]) : 2000, argc > 10 ? atoi(argv[10]) : 30);
}

static int paths(int argc, char** argv) {
  if (argc < 7 || argc - 6 > 16) return 2;
  int samples = atoi(argv[2]), warmup_s = atoi(argv[4]);
  long gap_us = atol(argv[3]);
  struct path ps[16];
  int n = argc - 6;
  if (samples <= 0) return 2;
  for (int k = 0; k < n; ++k) {
    int r = open_path(&ps[k], argv[6 + k], argv[5], 1, samples);
    if (r == 2) return 2;
    if (r != 0) {
      perror("can_probe: setup");
      return 1;
    }
  }
  return measure(ps, n, samples, gap_us, warmup_s);
}

static int pace(int argc, char** argv) {
  if (argc != 6) return 2;
  canid_t id = (canid_t)strtoul(argv[3], NULL, 0);
  double rate = atof(argv[4]), seconds = atof(argv[5]);
  int s = open_can(argv[2], id, 0, 0, 0); /* no filter: it receives nothing */
  if (s < 0 || rate <= 0) {
    perror("can_probe: setup");
    return 1;
  }
  int64_t start = mono_ns(), end = start + (int64_t)(seconds * 1e9);
  uint64_t sent = 0, errors = 0;
  for (;;) {
    int64_t now = mono_ns();
    if (now >= end) break;
    uint64_t due = (uint64_t)((double)(now - start) * rate / 1e9) + 1;
    /* Every frame due, in one sendmmsg (at most 256): the bus's frames, not the sender's calls. */
    struct can_frame frames[256];
    struct iovec iov[256];
    struct mmsghdr msgs[256];
    unsigned n = 0;
    for (; sent + n < due && n < 256; ++n) {
      frames[n] = stimulus(id, (unsigned)(sent + n));
      iov[n] = (struct iovec){.iov_base = &frames[n], .iov_len = sizeof frames[n]};
      memset(&msgs[n], 0, sizeof msgs[n]);
      msgs[n].msg_hdr.msg_iov = &iov[n];
      msgs[n].msg_hdr.msg_iovlen = 1;
    }
    int r = n ? sendmmsg(s, msgs, n, 0) : 0;
    if (r > 0) sent += (uint64_t)r;
    if (r < 0 || (unsigned)r < n) {
      if (r < 0 && errno != ENOBUFS && errno != EAGAIN) {
        perror("can_probe: sendmmsg");
        return 1;
      }
      ++errors;
      struct timespec pause = {.tv_sec = 0, .tv_nsec = 100000}; /* the queue drains */
      nanosleep(&pause, NULL);
    }
    int64_t next = start + (int64_t)((double)sent * 1e9 / rate);
    struct timespec ts = {.tv_sec = next / 1000000000, .tv_nsec = next % 1000000000};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
  }
  double took = (double)(mono_ns() - start) / 1e9;
  printf("sent %llu in %.1f s: %.0f frames/s, %llu send errors (ENOBUFS)\n", (unsigned long long)sent, took,
         (double)sent / took, (unsigned long long)errors);
  return 0;
}

int main(int argc, char** argv) {
  int rc = 2;
  if (argc > 1 && strcmp(argv[1], "latency") == 0) rc = latency(argc, argv);
  if (argc > 1 && strcmp(argv[1], "paths") == 0) rc = paths(argc, argv);
  if (argc > 1 && strcmp(argv[1], "pace") == 0) rc = pace(argc, argv);
  if (rc == 2)
    fprintf(stderr,
            "usage: %s latency IN_IF IN_ID OUT_IF OUT_ID copy|cia852 SAMPLES LOG [GAP_US] [WARMUP_S]\n"
            "       %s paths SAMPLES GAP_US WARMUP_S LOG_PREFIX NAME:IN_IF:IN_ID:OUT_IF:OUT_ID:copy|cia852 ...\n"
            "       %s pace IF ID RATE SECONDS\n",
            argv[0], argv[0], argv[0]);
  return rc;
}
