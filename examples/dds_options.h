/* What every DDS example takes on its command line — --domain, --partition, --network — and the
 * participant they describe. The network configuration goes with the domain, as in the gateway
 * (docs/guides/dds-lcm.md#network): "loopback" (the default) keeps everything on this host, an
 * interface name selects the cab network, "default" leaves Cyclone's own configuration
 * (CYCLONEDDS_URI) alone. */
#ifndef OEGW_DDS_OPTIONS_H
#define OEGW_DDS_OPTIONS_H

#include <getopt.h>

#include "dds/dds.h"

/* DDS Security (docs/guides/secure-dds.md): the application's six files, as the gateway's
 * publish.dds.security names them; all or none. */
enum { DDS_SECURITY_FILES = 6 };

struct dds_options {
  unsigned domain;
  const char* partition;
  const char* network;
  const char* security[DDS_SECURITY_FILES]; /* identity CA, certificate, key, permissions CA, governance, permissions */
  dds_entity_t created_domain;              /* the domain dds_options_participant created for the network (0: none) */
};

#define DDS_OPTIONS_DEFAULT \
  { 0, "oegw", "loopback", {0}, 0 }
/* The getopt_long entries; the values are 'D', 'P', 'N' and 0x100 + the security file's index. */
#define DDS_OPTIONS_LONG                                                                                    \
  {"domain", required_argument, NULL, 'D'}, {"partition", required_argument, NULL, 'P'},                    \
      {"network", required_argument, NULL, 'N'}, {"identity-ca", required_argument, NULL, 0x100},           \
      {"certificate", required_argument, NULL, 0x101}, {"private-key", required_argument, NULL, 0x102},     \
      {"permissions-ca", required_argument, NULL, 0x103}, {"governance", required_argument, NULL, 0x104}, { \
    "permissions", required_argument, NULL, 0x105                                                           \
  }
#define DDS_OPTIONS_USAGE                                                  \
  "[--domain 0..232] [--partition P] [--network loopback|IFACE|default]\n" \
  "       [--identity-ca F --certificate F --private-key F --permissions-ca F --governance F --permissions F]"
#define DDS_OPTIONS_HELP                                                                              \
  "  --domain D        DDS domain (default 0)\n"                                                      \
  "  --partition P     the gateway's publish.dds.partition (default oegw; the demo's: oegw-demo)\n"   \
  "  --network N       loopback (default: nothing leaves this host), an interface name, or default\n" \
  "                    (Cyclone's own configuration, CYCLONEDDS_URI)\n"                               \
  "  --identity-ca F, --certificate F, --private-key F, --permissions-ca F, --governance F,\n"        \
  "  --permissions F   DDS Security: this application's identity and the cab's documents, all six\n"  \
  "                    (scripts/make-dds-security.sh makes them); not with --network default\n"

/* Takes option C (one of the above) with its value: 1 taken, 0 refused (said why on stderr),
 * -1 not one of these options. */
int dds_options_take(const char* prog, int c, const char* value, struct dds_options* o);

/* The participant and, with the partition, a subscriber or a publisher in it; < 0 (said why on
 * stderr) when Cyclone refuses. */
dds_entity_t dds_options_participant(const char* prog, struct dds_options* o);
/* Ends DDS before the program returns: the participant and the domain dds_options_participant
 * created for the network configuration. Deleting the participant alone leaves that domain (an
 * explicit dds_create_domain outlives its participants) and its threads running into exit(),
 * where OpenSSL's cleanup frees its locks while a receive thread still decrypts a DDS Security
 * message: a SIGSEGV seen under qemu-user, where that thread is slow. */
void dds_options_close(struct dds_options* o, dds_entity_t participant);
dds_entity_t dds_options_subscriber(const char* prog, dds_entity_t participant, const struct dds_options* o);
dds_entity_t dds_options_publisher(const char* prog, dds_entity_t participant, const struct dds_options* o);
/* Said on stderr by a reader whose SECONDS (0: stopped by a signal) passed with nothing from
 * TOPIC: what it waited for (topic, domain, partition, network), then the likeliest cause.
 * `oegw demo` publishes under its own partition, oegw-demo, a gateway under its
 * publish.dds.partition (default oegw), so a reader left at the default hears nothing from the
 * demo (docs/guides/dds-lcm.md#the-demo). */
void dds_options_nothing_received(const char* prog, const struct dds_options* o, const char* topic, double seconds);

#endif
