/* A minimal Cyclone DDS subscriber for oegw's joystick topic: copy it as a start.
 *
 *   dds_subscriber [--count N] [--timeout SECONDS] [--domain D] [--partition P] [--network loopback|IFACE|default]
 *
 * Prints one line per joystick sample:
 *   joystick instance=1 status=valid seq=7 ts_us=123 x=100 y=-5 z=0 buttons=0x01 memory=0x00 rx_us=130
 * (rx_us: CLOCK_MONOTONIC microseconds when the sample was taken, comparable with ts_us on this host).
 * Exits 0 after N samples (or at the timeout when no --count is given), 2 when the timeout comes first.
 * The default network is "loopback": the same loopback-only configuration the gateway applies in
 * tests and the demo, so nothing leaves the host. "default" leaves Cyclone's configuration
 * (CYCLONEDDS_URI) alone; an interface name selects the cab network.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "dds/dds.h"
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

int main(int argc, char** argv) {
  long count = -1;
  double timeout_s = 10.0;
  unsigned domain = 0;
  const char* partition = "oegw";
  const char* network = "loopback";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (strcmp(argv[i], "--count") == 0) count = atol(argv[i + 1]);
    else if (strcmp(argv[i], "--timeout") == 0) timeout_s = atof(argv[i + 1]);
    else if (strcmp(argv[i], "--domain") == 0) domain = (unsigned)atoi(argv[i + 1]);
    else if (strcmp(argv[i], "--partition") == 0) partition = argv[i + 1];
    else if (strcmp(argv[i], "--network") == 0) network = argv[i + 1];
    else {
      fprintf(stderr, "usage: %s [--count N] [--timeout S] [--domain D] [--partition P] [--network loopback|IFACE|default]\n", argv[0]);
      return 1;
    }
  }

  /* The network configuration goes with the domain, as in the gateway. */
  char xml[1024];
  if (strcmp(network, "loopback") == 0) {
    snprintf(xml, sizeof xml, "%s",
             "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
             "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
             "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery></Domain></CycloneDDS>");
  } else if (strcmp(network, "default") != 0) {
    snprintf(xml, sizeof xml,
             "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"%s\"/></Interfaces>"
             "</General></Domain></CycloneDDS>", network);
  } else {
    xml[0] = 0;
  }
  if (xml[0] != 0) {
    dds_entity_t d = dds_create_domain(domain, xml);
    if (d < 0) {
      fprintf(stderr, "cannot create DDS domain %u: %s\n", domain, dds_strretcode(d));
      return 1;
    }
  }
  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "cannot create DDS participant in domain %u: %s\n", domain, dds_strretcode(pp));
    return 1;
  }
  dds_qos_t* pq = dds_create_qos();
  dds_qset_partition1(pq, partition);
  dds_entity_t sub = dds_create_subscriber(pp, pq, NULL);
  dds_delete_qos(pq);

  /* The gateway's joystick QoS: reliable, keep-last 1 per instance. (Add dds_qset_deadline with
   * at least the gateway's publish period to be told when an instance stops arriving.) */
  dds_entity_t topic = dds_create_topic(pp, &oegw_Joystick_desc, "oegw/joystick", NULL, NULL);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  dds_entity_t reader = dds_create_reader(sub, topic, q, NULL);
  dds_delete_qos(q);
  if (topic < 0 || reader < 0) {
    fprintf(stderr, "cannot create the oegw/joystick reader\n");
    return 1;
  }

  dds_entity_t ws = dds_create_waitset(pp);
  dds_entity_t rc = dds_create_readcondition(reader, DDS_ANY_STATE);
  dds_waitset_attach(ws, rc, reader);
  printf("ready\n");
  fflush(stdout);

  const long long deadline = monotonic_us() + (long long)(timeout_s * 1e6);
  long received = 0;
  while (count < 0 || received < count) {
    long long left = deadline - monotonic_us();
    if (left <= 0) break;
    if (dds_waitset_wait(ws, NULL, 0, DDS_USECS(left)) <= 0) continue;
    void* samples[16] = {0};
    dds_sample_info_t infos[16];
    int n = dds_take(reader, samples, infos, 16, 16);
    long long rx = monotonic_us();
    for (int i = 0; i < n; i++) {
      if (!infos[i].valid_data) continue;
      const oegw_Joystick* j = (const oegw_Joystick*)samples[i];
      printf("joystick instance=%u status=%s seq=%u ts_us=%lld x=%d y=%d z=%d buttons=0x%02x memory=0x%02x rx_us=%lld\n",
             j->instance, status_name(j->status), (unsigned)j->seq, (long long)j->timestamp_us, j->x, j->y, j->z,
             j->buttons, j->memory, rx);
      received++;
    }
    if (n > 0) dds_return_loan(reader, samples, n);
    fflush(stdout);
  }
  dds_delete(pp);
  return (count >= 0 && received < count) ? 2 : 0;
}
