/* The command line of the command publishers (dds_command, lcm_command): which output FE and what
 * it is set to, checked against what the gateway takes (publish/oegw.idl IndicatorCommand,
 * DisplayCommand; docs/reference/mapping-file.md: indicators.1..8 with indicator[1..64],
 * display.1..8 with parameter[1..12], INTEGER16). A command carries the whole FE: the indicators it
 * does not light are off, the parameters it does not set are 0 (the gateway's "last write wins").
 * */
#ifndef OEGW_COMMAND_ARGS_H
#define OEGW_COMMAND_ARGS_H

#include "example_args.h"

#ifdef __cplusplus
extern "C" {
#endif

enum command_kind { COMMAND_NONE, COMMAND_INDICATORS, COMMAND_DISPLAY };

struct command_args {
  enum command_kind kind;
  unsigned instance;             /* 1..8 */
  unsigned long long indicators; /* bit i = indicator i+1 */
  short parameters[12];          /* parameter i+1 */
  int have_on, have_set;
};

/* The getopt_long entries: --on LIST ('o'), --set P=V,... ('s'). */
#define COMMAND_LONG \
  {"on", required_argument, NULL, 'o'}, { "set", required_argument, NULL, 's' }
#define COMMAND_USAGE "indicators INSTANCE --on LIST | display INSTANCE --set P=V[,P=V...]"
#define COMMAND_HELP                                                                                 \
  "  indicators INSTANCE --on LIST   light the indicators of LIST on indicators.INSTANCE (1..8),\n"  \
  "                    every other one off; LIST: numbers 1..64 and ranges, e.g. 1,3,5-8, or none\n" \
  "  display INSTANCE --set P=V,...  set display.INSTANCE's (1..8) parameters P (1..12) to V\n"      \
  "                    (-32768..32767), every other one to 0\n"

/* --on / --set: 1 taken, 0 refused (said why), -1 not one of these. */
int command_take(const char* prog, int c, const char* value, struct command_args* a);
/* KIND INSTANCE: 1 taken, 0 refused (said why). */
int command_positional(const char* prog, int index, const char* arg, struct command_args* a);
/* After the whole line: the FE named and the option of its kind (only that) given; 0 said why. */
int command_complete(const char* prog, const struct command_args* a);
/* "indicators.1 indicators=0x0000000000000005 (on: 1,3)" / "display.1 parameters=100,-5,0,..." */
void command_text(char* out, size_t size, const struct command_args* a);

#ifdef __cplusplus
}
#endif

#endif
