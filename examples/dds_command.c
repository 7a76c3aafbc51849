/* Commands the gateway's indicators and displays over DDS (topics oegw/indicators, oegw/display):
 * copy it as a start.
 *
 *   dds_command indicators 1 --on 1,3          indicators 1 and 3 of indicators.1 on, the others off
 *   dds_command display 1 --set 1=100,2=-5     display.1 parameters 1 and 2, the others 0
 *   [--timeout SECONDS] [--domain D] [--partition P] [--network loopback|IFACE|default]
 *
 * It waits (up to the timeout, default 5 s) for a reader of the topic — the gateway — to be
 * discovered, writes the command and waits for the reader's acknowledgement: exit 0 then, 3 when
 * no reader came or it did not acknowledge, 2 for a command line it refuses, 1 when DDS cannot be
 * opened. The gateway takes the command when the FE's mapping-file `sources` list dds; otherwise
 * it counts it in refused_commands (dds_status shows it).
 */
#include <stdio.h>
#include <string.h>

#include "command_args.h"
#include "dds/dds.h"
#include "dds_options.h"
#include "oegw.h"

struct options {
  struct command_args command;
  double timeout_s;
  struct dds_options dds;
};

static void usage(FILE* to, const char* prog) {
  fprintf(to,
          "usage: %s " COMMAND_USAGE
          "\n"
          "       [--timeout SECONDS] " DDS_OPTIONS_USAGE
          "\n"
          "Sends one command to the gateway's indicators or display over DDS.\n" COMMAND_HELP
          "  --timeout S       wait at most S seconds for the gateway's reader and its acknowledgement (default "
          "5)\n" DDS_OPTIONS_HELP "  --help            this text\n",
          prog);
}

static int take(const char* prog, int c, const char* value, void* ctx) {
  struct options* o = ctx;
  const int dds = dds_options_take(prog, c, value, &o->dds);
  if (dds >= 0) return dds;
  const int command = command_take(prog, c, value, &o->command);
  if (command >= 0) return command;
  return c == 't' && example_parse_seconds(prog, "--timeout", value, &o->timeout_s);
}

static int positional(const char* prog, int index, const char* arg, void* ctx) {
  return command_positional(prog, index, arg, &((struct options*)ctx)->command);
}

static const struct option longs[] = {COMMAND_LONG,
                                      {"timeout", required_argument, NULL, 't'},
                                      {"help", no_argument, NULL, 'h'},
                                      DDS_OPTIONS_LONG,
                                      {NULL, 0, NULL, 0}};

/* Waits for the gateway's reader to be discovered: 1 when it was, before TIMEOUT. */
static int wait_for_reader(dds_entity_t pp, dds_entity_t writer, dds_duration_t timeout) {
  dds_set_status_mask(writer, DDS_PUBLICATION_MATCHED_STATUS);
  const dds_entity_t ws = dds_create_waitset(pp);
  dds_waitset_attach(ws, writer, writer);
  const dds_time_t deadline = dds_time() + timeout;
  dds_publication_matched_status_t st = {0};
  while (dds_get_publication_matched_status(writer, &st) == DDS_RETCODE_OK && st.current_count == 0 &&
         dds_time() < deadline)
    dds_waitset_wait_until(ws, NULL, 0, deadline);
  dds_delete(ws);
  return st.current_count > 0;
}

/* The sample of the command and its topic. */
static dds_entity_t command_topic(dds_entity_t pp, const struct command_args* a, oegw_IndicatorCommand* ind,
                                  oegw_DisplayCommand* disp) {
  if (a->kind == COMMAND_INDICATORS) {
    ind->instance = (uint8_t)a->instance;
    ind->indicators = a->indicators;
    return dds_create_topic(pp, &oegw_IndicatorCommand_desc, "oegw/indicators", NULL, NULL);
  }
  disp->instance = (uint8_t)a->instance;
  memcpy(disp->parameters, a->parameters, sizeof disp->parameters);
  return dds_create_topic(pp, &oegw_DisplayCommand_desc, "oegw/display", NULL, NULL);
}

int main(int argc, char** argv) {
  struct options o = {{COMMAND_NONE, 0, 0, {0}, 0, 0}, 5.0, DDS_OPTIONS_DEFAULT};
  const char* prog = example_prog(argv[0]);
  const int exit = example_parse_options(argc, argv, longs, take, positional, usage, &o);
  if (exit >= 0) return exit;
  if (!command_complete(prog, &o.command)) {
    usage(stderr, prog);
    return EXAMPLE_EXIT_USAGE;
  }
  const dds_entity_t pp = dds_options_participant(prog, &o.dds);
  if (pp < 0) return EXAMPLE_EXIT_SETUP;
  const dds_entity_t pub = dds_options_publisher(prog, pp, &o.dds);
  oegw_IndicatorCommand ind = {0};
  oegw_DisplayCommand disp = {0};
  const dds_entity_t topic = command_topic(pp, &o.command, &ind, &disp);
  const char* topic_name = o.command.kind == COMMAND_INDICATORS ? "oegw/indicators" : "oegw/display";
  /* The gateway's command QoS: reliable, keep-last 1 per instance. */
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t writer = dds_create_writer(pub, topic, q, NULL);
  dds_delete_qos(q);
  if (pub < 0 || topic < 0 || writer < 0) {
    fprintf(stderr, "%s: cannot create the %s writer\n", prog, topic_name);
    dds_options_close(&o.dds, pp);
    return EXAMPLE_EXIT_SETUP;
  }
  const dds_duration_t timeout = (dds_duration_t)(o.timeout_s * 1e9);
  char text[512];
  command_text(text, sizeof text, &o.command);
  int status = EXAMPLE_EXIT_INCOMPLETE;
  if (!wait_for_reader(pp, writer, timeout)) {
    fprintf(stderr, "%s: no reader of %s (the gateway) in domain %u, partition %s within %g s: not sent\n", prog,
            topic_name, o.dds.domain, o.dds.partition, o.timeout_s);
  } else if (dds_write(writer, o.command.kind == COMMAND_INDICATORS ? (const void*)&ind : (const void*)&disp) < 0 ||
             dds_wait_for_acks(writer, timeout) != DDS_RETCODE_OK) {
    fprintf(stderr, "%s: %s: not acknowledged within %g s\n", prog, text, o.timeout_s);
  } else {
    printf("sent %s on %s\n", text, topic_name);
    status = EXAMPLE_EXIT_OK;
  }
  dds_options_close(&o.dds, pp);
  return status;
}
