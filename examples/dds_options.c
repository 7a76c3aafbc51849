#include "dds_options.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
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
    default:
      if (c >= 0x100 && c < 0x100 + DDS_SECURITY_FILES) {
        /* The path goes into Cyclone's XML as a file: URI: nothing that XML would read as markup. */
        if (value[0] == 0 || strpbrk(value, "<>&\"'") != NULL) {
          fprintf(stderr, "%s: a DDS Security file '%s': expected a path without < > & or quotes\n", prog, value);
          return 0;
        }
        o->security[c - 0x100] = value;
        return 1;
      }
      return -1;
  }
}

/* <Security> for the domain, the files as file: URIs (absolute: the domain may outlive a chdir). */
static int security_xml(const char* prog, const struct dds_options* o, char* out, size_t size) {
  static const char* const names[DDS_SECURITY_FILES] = {"--identity-ca",    "--certificate", "--private-key",
                                                        "--permissions-ca", "--governance",  "--permissions"};
  char path[DDS_SECURITY_FILES][PATH_MAX];
  int given = 0;
  for (int i = 0; i < DDS_SECURITY_FILES; i++) given += o->security[i] != NULL;
  out[0] = 0;
  if (given == 0) return 1;
  for (int i = 0; i < DDS_SECURITY_FILES; i++) {
    if (o->security[i] == NULL) {
      fprintf(stderr, "%s: DDS Security needs all six files; %s is missing\n", prog, names[i]);
      return 0;
    }
    if (realpath(o->security[i], path[i]) == NULL) {
      fprintf(stderr, "%s: %s %s: %s\n", prog, names[i], o->security[i], strerror(errno));
      return 0;
    }
  }
  if (strcmp(o->network, "default") == 0) {
    fprintf(stderr, "%s: DDS Security goes with the domain's configuration: give --network loopback or an interface\n",
            prog);
    return 0;
  }
  const int n = snprintf(out, size,
                         "<Security><Authentication><IdentityCA>file:%s</IdentityCA><IdentityCertificate>file:%s"
                         "</IdentityCertificate><PrivateKey>file:%s</PrivateKey></Authentication><AccessControl>"
                         "<PermissionsCA>file:%s</PermissionsCA><Governance>file:%s</Governance><Permissions>file:%s"
                         "</Permissions></AccessControl></Security>",
                         path[0], path[1], path[2], path[3], path[4], path[5]);
  if (n < 0 || (size_t)n >= size) {
    fprintf(stderr, "%s: the DDS Security paths are too long\n", prog);
    return 0;
  }
  return 1;
}

dds_entity_t dds_options_participant(const char* prog, struct dds_options* o) {
  static char security[8 * PATH_MAX];
  static char xml[9 * PATH_MAX];
  if (!security_xml(prog, o, security, sizeof security)) return DDS_RETCODE_BAD_PARAMETER;
  xml[0] = 0;
  if (strcmp(o->network, "loopback") == 0) {
    snprintf(xml, sizeof xml,
             "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
             "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
             "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>%s</Domain></CycloneDDS>",
             security);
  } else if (strcmp(o->network, "default") != 0) {
    snprintf(xml, sizeof xml,
             "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"%s\"/></Interfaces>"
             "</General>%s</Domain></CycloneDDS>",
             o->network, security);
  }
  if (xml[0] != 0) {
    const dds_entity_t d = dds_create_domain(o->domain, xml);
    if (d < 0) {
      fprintf(stderr, "%s: cannot create DDS domain %u (network %s): %s\n", prog, o->domain, o->network,
              dds_strretcode(d));
      return d;
    }
    o->created_domain = d;
  }
  const dds_entity_t pp = dds_create_participant(o->domain, NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "%s: cannot create a DDS participant in domain %u%s: %s\n", prog, o->domain,
            security[0] != 0 ? " with DDS Security (Cyclone's log above says why)" : "", dds_strretcode(pp));
    dds_options_close(o, 0);
  }
  return pp;
}

void dds_options_close(struct dds_options* o, dds_entity_t participant) {
  if (participant > 0) dds_delete(participant);
  /* Its threads stopped and joined here, before exit() runs the libraries' cleanup. */
  if (o->created_domain > 0) dds_delete(o->created_domain);
  o->created_domain = 0;
}

static dds_entity_t in_partition(const char* prog, dds_entity_t pp, const struct dds_options* o, int publisher) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_partition1(q, o->partition);
  const dds_entity_t e = publisher ? dds_create_publisher(pp, q, NULL) : dds_create_subscriber(pp, q, NULL);
  dds_delete_qos(q);
  if (e < 0)
    fprintf(stderr, "%s: cannot create a DDS %s in partition %s: %s\n", prog, publisher ? "publisher" : "subscriber",
            o->partition, dds_strretcode(e));
  return e;
}

dds_entity_t dds_options_subscriber(const char* prog, dds_entity_t participant, const struct dds_options* o) {
  return in_partition(prog, participant, o, 0);
}

dds_entity_t dds_options_publisher(const char* prog, dds_entity_t participant, const struct dds_options* o) {
  return in_partition(prog, participant, o, 1);
}

void dds_options_nothing_received(const char* prog, const struct dds_options* o, const char* topic, double seconds) {
  char when[64];
  if (seconds > 0) snprintf(when, sizeof when, "within %g s", seconds);
  else snprintf(when, sizeof when, "before it was stopped");
  fprintf(stderr, "%s: nothing on %s %s (domain %u, partition %s, network %s)\n", prog, topic, when, o->domain,
          o->partition, o->network);
  if (strcmp(o->partition, "oegw-demo") != 0)
    fprintf(stderr,
            "%s: the demo publishes partition oegw-demo: --partition oegw-demo; a gateway its publish.dds.partition "
            "(default oegw), publish.dds.domain and publish.dds.network\n",
            prog);
  else
    fprintf(stderr,
            "%s: is `oegw demo` running (on this computer: --network loopback)? A gateway publishes its "
            "publish.dds.partition (default oegw): --partition oegw\n",
            prog);
}
