/* Prints what the gateway's status (topic oegw/status) says as it changes: copy it as a start.
 *
 *   dds_status [--timeout SECONDS] [--every] [--domain D] [--partition P] [--network loopback|IFACE|default]
 *
 * One line per change (the first status: every line), the same lines as lcm_status:
 *   upstream state=operational
 *   subdevice right_grip node=11h state=operational vendor=0000012Eh product=... name="MFG" sw="1.2" err=00h
 *   emcy right_grip node=11h count=1 last=8130h reg=11h msef=00 00 00 00 00 ts_us=5000
 *   upstream_emcy node=05h count=1 last=8130h reg=11h msef=01 02 03 04 05 ts_us=5000
 *   active_emcys 7000h                  (the gateway's own active EMCYs; "none")
 *   refused_commands 2                  (commands refused since start: rising = someone is refused)
 * and with --every a line per status message first:
 *   status seq=12 upstream=operational subdevices=5 active=none refused=0
 * A sub-device's line comes again when its state or what it said about itself at boot changes.
 * Exits 0 at the timeout (default: none, Ctrl-C) when a status came, 3 when none came, 2 for a
 * command line it refuses, 1 when DDS cannot be opened.
 */
#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "dds/dds.h"
#include "dds_options.h"
#include "example_args.h"
#include "oegw.h"

struct options {
  double timeout_s; /* 0: none */
  int every;
  struct dds_options dds;
};

static void usage(FILE* to, const char* prog) {
  fprintf(to,
          "usage: %s [--timeout SECONDS] [--every] " DDS_OPTIONS_USAGE
          "\n"
          "Prints the gateway's status (topic oegw/status) as it changes: sub-device states and identities,\n"
          "EMCYs, the gateway's active EMCYs, refused commands; one line each.\n"
          "  --timeout S       stop after S seconds (default: run until Ctrl-C)\n"
          "  --every           also a line for every status message\n" DDS_OPTIONS_HELP
          "  --help            this text\n",
          prog);
}

static int take(const char* prog, int c, const char* value, void* ctx) {
  struct options* o = ctx;
  const int dds = dds_options_take(prog, c, value, &o->dds);
  if (dds >= 0) return dds;
  if (c == 'e') return o->every = 1;
  return c == 't' && example_parse_seconds(prog, "--timeout", value, &o->timeout_s);
}

static const struct option longs[] = {{"timeout", required_argument, NULL, 't'},
                                      {"every", no_argument, NULL, 'e'},
                                      {"help", no_argument, NULL, 'h'},
                                      DDS_OPTIONS_LONG,
                                      {NULL, 0, NULL, 0}};

/* What the last status said, to print only what changed. */
enum { MAX_SUBDEVICES = 128, LINE = 1024 };
struct seen_subdevice {
  char name[64];
  char line[LINE];
  unsigned long long emcys;
};
static struct {
  int any;
  char upstream[64];
  char active[256];
  unsigned long long refused;
  struct seen_subdevice subdevices[MAX_SUBDEVICES];
  int n_subdevices;
  unsigned long long upstream_emcys[128]; /* by node-ID */
} seen;

static struct seen_subdevice* seen_subdevice(const char* name) {
  for (int i = 0; i < seen.n_subdevices; i++)
    if (strcmp(seen.subdevices[i].name, name) == 0) return &seen.subdevices[i];
  if (seen.n_subdevices == MAX_SUBDEVICES) return NULL;
  struct seen_subdevice* s = &seen.subdevices[seen.n_subdevices++];
  snprintf(s->name, sizeof s->name, "%s", name);
  return s;
}

/* " last=8130h reg=11h msef=01 02 03 04 05 ts_us=5000" (lcm_print.cpp's emcy_text) */
static void emcy_text(char* out, size_t size, const oegw_Emcy* e) {
  snprintf(out, size, " last=%04Xh reg=%02Xh msef=%02x %02x %02x %02x %02x ts_us=%lld", e->code, e->error_register,
           e->msef[0], e->msef[1], e->msef[2], e->msef[3], e->msef[4], (long long)e->timestamp_us);
}

/* The fields the sub-device had at its last boot, by its `present` mask (lcm_print.cpp's identity_text). */
static void identity_text(char* out, size_t size, const oegw_SubdeviceIdentity* id) {
  const unsigned long numbers[4] = {id->vendor_id, id->product_code, id->revision, id->serial};
  static const char* const number_names[4] = {"vendor", "product", "revision", "serial"};
  const char* texts[3] = {id->device_name, id->hardware_version, id->software_version};
  static const char* const text_names[3] = {"name", "hw", "sw"};
  size_t n = 0;
  out[0] = 0;
  if (id->present == 0) snprintf(out, size, " identity=none");
  for (int k = 0; k < 4 && n < size; k++)
    if (id->present & (1u << k)) n += (size_t)snprintf(out + n, size - n, " %s=%08lXh", number_names[k], numbers[k]);
  for (int k = 0; k < 3 && n < size; k++)
    if (id->present & (1u << (4 + k))) n += (size_t)snprintf(out + n, size - n, " %s=\"%s\"", text_names[k], texts[k]);
  if ((id->present & 0x80u) && n < size) snprintf(out + n, size - n, " err=%02Xh", id->error_register);
}

static void print_subdevice(const oegw_SubdeviceState* d) {
  struct seen_subdevice* s = seen_subdevice(d->name);
  char id[512], line[LINE], emcy[128];
  identity_text(id, sizeof id, &d->identity);
  snprintf(line, sizeof line, "subdevice %s node=%02Xh state=%s%s", d->name, d->node_id, d->state, id);
  if (s == NULL || strcmp(s->line, line) != 0) printf("%s\n", line);
  if (d->emcy_count > 0 && (s == NULL || s->emcys != d->emcy_count)) {
    emcy_text(emcy, sizeof emcy, &d->last_emcy);
    printf("emcy %s node=%02Xh count=%llu%s\n", d->name, d->node_id, (unsigned long long)d->emcy_count, emcy);
  }
  if (s != NULL) {
    snprintf(s->line, sizeof s->line, "%s", line);
    s->emcys = d->emcy_count;
  }
}

static void print_status(const oegw_GatewayStatus* st, int every) {
  char active[256] = "";
  size_t n = 0;
  for (uint32_t i = 0; i < st->active_emcys._length && n < sizeof active; i++)
    n += (size_t)snprintf(active + n, sizeof active - n, "%s%04Xh", i ? "," : "", st->active_emcys._buffer[i]);
  if (n == 0) snprintf(active, sizeof active, "none");
  if (every)
    printf("status seq=%u upstream=%s subdevices=%u active=%s refused=%llu\n", (unsigned)st->seq, st->upstream_state,
           (unsigned)st->subdevices._length, active, (unsigned long long)st->refused_commands);
  if (!seen.any || strcmp(seen.upstream, st->upstream_state) != 0) printf("upstream state=%s\n", st->upstream_state);
  for (uint32_t i = 0; i < st->subdevices._length; i++) print_subdevice(&st->subdevices._buffer[i]);
  for (uint32_t i = 0; i < st->upstream_emcys._length; i++) {
    const oegw_UpstreamEmcy* u = &st->upstream_emcys._buffer[i];
    char emcy[128];
    if (u->count == seen.upstream_emcys[u->node_id & 0x7F]) continue;
    seen.upstream_emcys[u->node_id & 0x7F] = u->count;
    emcy_text(emcy, sizeof emcy, &u->last);
    printf("upstream_emcy node=%02Xh count=%llu%s\n", u->node_id, (unsigned long long)u->count, emcy);
  }
  if (!seen.any || strcmp(seen.active, active) != 0) printf("active_emcys %s\n", active);
  if (!seen.any || seen.refused != st->refused_commands)
    printf("refused_commands %llu\n", (unsigned long long)st->refused_commands);
  snprintf(seen.upstream, sizeof seen.upstream, "%s", st->upstream_state);
  snprintf(seen.active, sizeof seen.active, "%s", active);
  seen.refused = st->refused_commands;
  seen.any = 1;
  fflush(stdout);
}

static volatile sig_atomic_t stop;
static void on_signal(int sig) {
  (void)sig;
  stop = 1;
}

int main(int argc, char** argv) {
  struct options o = {0, 0, DDS_OPTIONS_DEFAULT};
  const int exit = example_parse_options(argc, argv, longs, take, NULL, usage, &o);
  if (exit >= 0) return exit;
  const char* prog = example_prog(argv[0]);
  const dds_entity_t pp = dds_options_participant(prog, &o.dds);
  if (pp < 0) return EXAMPLE_EXIT_SETUP;
  const dds_entity_t sub = dds_options_subscriber(prog, pp, &o.dds);
  /* The gateway's status QoS: reliable, transient-local (so this reader gets the last status at
   * once); a deeper history than the writer's keep-last 1 so a slow terminal loses no change. */
  const dds_entity_t topic = dds_create_topic(pp, &oegw_GatewayStatus_desc, "oegw/status", NULL, NULL);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 16);
  const dds_entity_t reader = dds_create_reader(sub, topic, q, NULL);
  dds_delete_qos(q);
  if (sub < 0 || topic < 0 || reader < 0) {
    fprintf(stderr, "%s: cannot create the oegw/status reader\n", prog);
    dds_options_close(&o.dds, pp);
    return EXAMPLE_EXIT_SETUP;
  }
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);
  const dds_entity_t ws = dds_create_waitset(pp);
  dds_waitset_attach(ws, dds_create_readcondition(reader, DDS_ANY_STATE), reader);
  printf("ready\n");
  fflush(stdout);

  const dds_time_t deadline = o.timeout_s > 0 ? dds_time() + (dds_time_t)(o.timeout_s * 1e9) : DDS_NEVER;
  /* Woken every 100 ms at least, to see a signal. */
  while (!stop && dds_time() < deadline) {
    if (dds_waitset_wait(ws, NULL, 0, DDS_MSECS(100)) <= 0) continue;
    void* samples[16] = {0};
    dds_sample_info_t infos[16];
    const int n = dds_take(reader, samples, infos, 16, 16);
    for (int i = 0; i < n; i++)
      if (infos[i].valid_data) print_status((const oegw_GatewayStatus*)samples[i], o.every);
    if (n > 0) dds_return_loan(reader, samples, n);
  }
  dds_options_close(&o.dds, pp);
  if (!seen.any) dds_options_nothing_received(prog, &o.dds, "oegw/status", o.timeout_s);
  return seen.any ? EXAMPLE_EXIT_OK : EXAMPLE_EXIT_INCOMPLETE;
}
