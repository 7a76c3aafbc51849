/* A minimal Cyclone DDS subscriber for oegw's joystick topic: copy it as a start.
 *
 *   dds_subscriber [--count N] [--timeout SECONDS] [--domain D] [--partition P] [--network loopback|IFACE|default]
 *
 * Prints one line per joystick sample:
 *   joystick instance=1 status=valid seq=7 ts_us=123 x=100 y=-5 z=0 buttons=0x01 memory=0x00 rx_us=130
 * (rx_us: CLOCK_MONOTONIC microseconds when the sample was taken, comparable with ts_us on this host).
 * Exits 0 after N samples (or at the timeout when no --count is given), 3 when the timeout comes
 * first, 2 for a command line it refuses, 1 when DDS cannot be opened. A timeout with nothing
 * received says on stderr what it waited for and the likely cause (dds_options_nothing_received).
 * The default network is "loopback": the same loopback-only configuration the gateway applies in
 * tests and the demo, so nothing leaves the host (dds_options.h).
 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "dds/dds.h"
#include "dds_options.h"
#include "example_args.h"
#include "oegw.h"

static const char* status_name(oegw_FeStatus s) {
  switch (s) {
    case oegw_FE_VALID: return "valid";
    case oegw_FE_ERROR: return "error";
    case oegw_FE_NOT_AVAILABLE: return "not_available";
    case oegw_FE_STALE: return "stale";
    case oegw_FE_OFFLINE: return "offline";
  }
  return "?";
}

static long long monotonic_us(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (long long)ts.tv_sec * 1000000LL + ts.tv_nsec / 1000;
}

struct options {
  long count; /* -1: until the timeout */
  double timeout_s;
  struct dds_options dds;
};

static void usage(FILE* to, const char* prog) {
  fprintf(to,
          "usage: %s [--count N] [--timeout SECONDS] " DDS_OPTIONS_USAGE
          "\n"
          "Prints the gateway's joystick samples (topic oegw/joystick), one line each.\n"
          "  --count N         exit 0 after N samples (exit 3 if the timeout comes first)\n"
          "  --timeout S       stop after S seconds (default 10)\n" DDS_OPTIONS_HELP "  --help            this text\n",
          prog);
}

static int take(const char* prog, int c, const char* value, void* ctx) {
  struct options* o = ctx;
  const int dds = dds_options_take(prog, c, value, &o->dds);
  if (dds >= 0) return dds;
  if (c == 'c') return example_parse_long(prog, "--count", value, 1, 1000000000L, &o->count);
  return c == 't' && example_parse_seconds(prog, "--timeout", value, &o->timeout_s);
}

static const struct option longs[] = {{"count", required_argument, NULL, 'c'},
                                      {"timeout", required_argument, NULL, 't'},
                                      {"help", no_argument, NULL, 'h'},
                                      DDS_OPTIONS_LONG,
                                      {NULL, 0, NULL, 0}};

int main(int argc, char** argv) {
  struct options o = {-1, 10.0, DDS_OPTIONS_DEFAULT};
  const int exit = example_parse_options(argc, argv, longs, take, NULL, usage, &o);
  if (exit >= 0) return exit;
  const char* prog = example_prog(argv[0]);
  const dds_entity_t pp = dds_options_participant(prog, &o.dds);
  if (pp < 0) return EXAMPLE_EXIT_SETUP;
  const dds_entity_t sub = dds_options_subscriber(prog, pp, &o.dds);

  /* The gateway's joystick QoS: reliable, keep-last 1 per instance. (Add dds_qset_deadline with
   * at least the gateway's publish period to be told when an instance stops arriving.) */
  dds_entity_t topic = dds_create_topic(pp, &oegw_Joystick_desc, "oegw/joystick", NULL, NULL);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  dds_entity_t reader = dds_create_reader(sub, topic, q, NULL);
  dds_delete_qos(q);
  if (sub < 0 || topic < 0 || reader < 0) {
    fprintf(stderr, "%s: cannot create the oegw/joystick reader\n", prog);
    dds_options_close(&o.dds, pp);
    return EXAMPLE_EXIT_SETUP;
  }

  dds_entity_t ws = dds_create_waitset(pp);
  dds_entity_t rc = dds_create_readcondition(reader, DDS_ANY_STATE);
  dds_waitset_attach(ws, rc, reader);
  printf("ready\n");
  fflush(stdout);

  const long long deadline = monotonic_us() + (long long)(o.timeout_s * 1e6);
  long received = 0;
  while (o.count < 0 || received < o.count) {
    long long left = deadline - monotonic_us();
    if (left <= 0) break;
    if (dds_waitset_wait(ws, NULL, 0, DDS_USECS(left)) <= 0) continue;
    void* samples[16] = {0};
    dds_sample_info_t infos[16];
    int n = dds_take(reader, samples, infos, 16, 16);
    long long rx = monotonic_us();
    /* A take can return more samples than are still wanted (joystick 1 and 2 are written at the
     * same instant): --count N prints exactly N, the rest of the batch is returned unprinted. */
    for (int i = 0; i < n && (o.count < 0 || received < o.count); i++) {
      if (!infos[i].valid_data) continue;
      const oegw_Joystick* j = (const oegw_Joystick*)samples[i];
      printf(
          "joystick instance=%u status=%s seq=%u ts_us=%lld x=%d y=%d z=%d buttons=0x%02x memory=0x%02x rx_us=%lld\n",
          j->instance, status_name(j->status), (unsigned)j->seq, (long long)j->timestamp_us, j->x, j->y, j->z,
          j->buttons, j->memory, rx);
      received++;
    }
    if (n > 0) dds_return_loan(reader, samples, n);
    fflush(stdout);
  }
  dds_options_close(&o.dds, pp);
  if (received == 0) dds_options_nothing_received(prog, &o.dds, "oegw/joystick", o.timeout_s);
  else if (o.count >= 0 && received < o.count)
    fprintf(stderr, "%s: %ld of the %ld samples within %g s\n", prog, received, o.count, o.timeout_s);
  return (o.count >= 0 && received < o.count) ? EXAMPLE_EXIT_INCOMPLETE : EXAMPLE_EXIT_OK;
}
