#include "dds_options.h"

#include <ctype.h>
#include <stdio.h>
#include <string.h>

#include "example_args.h"

/* An interface name goes into Cyclone's XML: letters, digits and . _ - : only (and what the
 * kernel allows, at most 15 characters). */
static int interface_name_ok(const char* s) {
  const size_t n = strlen(s);
  if (n == 0 || n > 15) return 0;
  for (size_t i = 0; i < n; i++)
    if (!isalnum((unsigned char)s[i]) && strchr("._-:", s[i]) == NULL) return 0;
  return 1;
}

int dds_options_take(const char* prog, int c, const char* value, struct dds_options* o) {
  long v = 0;
  switch (c) {
    case 'D':
      /* 232: the highest domain the DDSI port mapping (7400 + 250 * domain + ...) leaves in range. */
      if (!example_parse_long(prog, "--domain", value, 0, 232, &v)) return 0;
      o->domain = (unsigned)v;
      return 1;
    case 'P':
      if (value[0] == 0) {
        fprintf(stderr, "%s: --partition: the partition name is empty\n", prog);
        return 0;
      }
      o->partition = value;
      return 1;
    case 'N':
      if (strcmp(value, "loopback") != 0 && strcmp(value, "default") != 0 && !interface_name_ok(value)) {
        fprintf(stderr, "%s: --network: '%s' is not loopback, default or an interface name\n", prog, value);
        return 0;
      }
      o->network = value;
      return 1;
    default: return -1;
  }
}

dds_entity_t dds_options_participant(const char* prog, const struct dds_options* o) {
  char xml[1024] = "";
  if (strcmp(o->network, "loopback") == 0) {
    snprintf(xml, sizeof xml, "%s",
             "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
             "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
             "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery></Domain></CycloneDDS>");
  } else if (strcmp(o->network, "default") != 0) {
    snprintf(xml, sizeof xml,
             "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"%s\"/></Interfaces>"
             "</General></Domain></CycloneDDS>", o->network);
  }
  if (xml[0] != 0) {
    const dds_entity_t d = dds_create_domain(o->domain, xml);
    if (d < 0) {
      fprintf(stderr, "%s: cannot create DDS domain %u (network %s): %s\n", prog, o->domain, o->network, dds_strretcode(d));
      return d;
    }
  }
  const dds_entity_t pp = dds_create_participant(o->domain, NULL, NULL);
  if (pp < 0) fprintf(stderr, "%s: cannot create a DDS participant in domain %u: %s\n", prog, o->domain, dds_strretcode(pp));
  return pp;
}

static dds_entity_t in_partition(const char* prog, dds_entity_t pp, const struct dds_options* o, int publisher) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_partition1(q, o->partition);
  const dds_entity_t e = publisher ? dds_create_publisher(pp, q, NULL) : dds_create_subscriber(pp, q, NULL);
  dds_delete_qos(q);
  if (e < 0) fprintf(stderr, "%s: cannot create a DDS %s in partition %s: %s\n", prog, publisher ? "publisher" : "subscriber",
                     o->partition, dds_strretcode(e));
  return e;
}

dds_entity_t dds_options_subscriber(const char* prog, dds_entity_t participant, const struct dds_options* o) {
  return in_partition(prog, participant, o, 0);
}

dds_entity_t dds_options_publisher(const char* prog, dds_entity_t participant, const struct dds_options* o) {
  return in_partition(prog, participant, o, 1);
}
