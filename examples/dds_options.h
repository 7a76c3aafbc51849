/* What every DDS example takes on its command line — --domain, --partition, --network — and the
 * participant they describe. The network configuration goes with the domain, as in the gateway
 * (README "Network"): "loopback" (the default) keeps everything on this host, an interface name
 * selects the cab network, "default" leaves Cyclone's own configuration (CYCLONEDDS_URI) alone. */
#ifndef OEGW_DDS_OPTIONS_H
#define OEGW_DDS_OPTIONS_H

#include <getopt.h>

#include "dds/dds.h"

struct dds_options {
  unsigned domain;
  const char* partition;
  const char* network;
};

#define DDS_OPTIONS_DEFAULT {0, "oegw", "loopback"}
/* The getopt_long entries; the values are 'D', 'P' and 'N'. */
#define DDS_OPTIONS_LONG \
  {"domain", required_argument, NULL, 'D'}, {"partition", required_argument, NULL, 'P'}, \
  {"network", required_argument, NULL, 'N'}
#define DDS_OPTIONS_USAGE "[--domain 0..232] [--partition P] [--network loopback|IFACE|default]"
#define DDS_OPTIONS_HELP \
  "  --domain D        DDS domain (default 0)\n" \
  "  --partition P     the gateway's publish.dds.partition (default oegw; the demo's: oegw-demo)\n" \
  "  --network N       loopback (default: nothing leaves this host), an interface name, or default\n" \
  "                    (Cyclone's own configuration, CYCLONEDDS_URI)\n"

/* Takes option C (one of the above) with its value: 1 taken, 0 refused (said why on stderr),
 * -1 not one of these options. */
int dds_options_take(const char* prog, int c, const char* value, struct dds_options* o);

/* The participant and, with the partition, a subscriber or a publisher in it; < 0 (said why on
 * stderr) when Cyclone refuses. */
dds_entity_t dds_options_participant(const char* prog, const struct dds_options* o);
dds_entity_t dds_options_subscriber(const char* prog, dds_entity_t participant, const struct dds_options* o);
dds_entity_t dds_options_publisher(const char* prog, dds_entity_t participant, const struct dds_options* o);

#endif
