#include "command_args.h"

#include <stdlib.h>
#include <string.h>

enum { MAX_INSTANCE = 8, MAX_INDICATOR = 64, PARAMETERS = 12 };

/* One element of an --on list, "N" or "A-B", into *bits. */
static int take_lamps(const char* prog, char* item, unsigned long long* bits) {
  char* dash = strchr(item, '-');
  long from = 0, to = 0;
  if (dash != NULL) *dash = 0;
  if (!example_parse_long(prog, "--on", item, 1, MAX_INDICATOR, &from)) return 0;
  to = from;
  if (dash != NULL && !example_parse_long(prog, "--on", dash + 1, from, MAX_INDICATOR, &to)) return 0;
  for (long i = from; i <= to; i++) *bits |= 1ULL << (i - 1);
  return 1;
}

/* One element of a --set list, "P=V". */
static int take_parameter(const char* prog, char* item, struct command_args* a, unsigned* given) {
  char* eq = strchr(item, '=');
  long p = 0, v = 0;
  if (eq == NULL) {
    fprintf(stderr, "%s: --set: '%s' is not PARAMETER=VALUE\n", prog, item);
    return 0;
  }
  *eq = 0;
  if (!example_parse_long(prog, "--set (parameter)", item, 1, PARAMETERS, &p) ||
      !example_parse_long(prog, "--set (value)", eq + 1, -32768, 32767, &v))
    return 0;
  if (*given & (1u << (p - 1))) {
    fprintf(stderr, "%s: --set: parameter %ld given twice\n", prog, p);
    return 0;
  }
  *given |= 1u << (p - 1);
  a->parameters[p - 1] = (short)v;
  return 1;
}

/* Each comma-separated element of VALUE to one of the two above. */
static int take_list(const char* prog, int c, const char* value, struct command_args* a) {
  char copy[512];
  unsigned given = 0;
  if (strlen(value) >= sizeof copy || value[0] == 0) {
    fprintf(stderr, "%s: %s: '%s' is not a list\n", prog, c == 'o' ? "--on" : "--set", value);
    return 0;
  }
  if (c == 'o' && strcmp(value, "none") == 0) return 1;
  strcpy(copy, value);
  char* save = NULL;
  for (char* item = strtok_r(copy, ",", &save); item != NULL; item = strtok_r(NULL, ",", &save))
    if (c == 'o' ? !take_lamps(prog, item, &a->indicators) : !take_parameter(prog, item, a, &given)) return 0;
  return 1;
}

int command_take(const char* prog, int c, const char* value, struct command_args* a) {
  if (c != 'o' && c != 's') return -1;
  int* have = c == 'o' ? &a->have_on : &a->have_set;
  if (*have) {
    fprintf(stderr, "%s: %s given twice\n", prog, c == 'o' ? "--on" : "--set");
    return 0;
  }
  *have = 1;
  return take_list(prog, c, value, a);
}

int command_positional(const char* prog, int index, const char* arg, struct command_args* a) {
  long instance = 0;
  switch (index) {
    case 0:
      a->kind = strcmp(arg, "indicators") == 0 ? COMMAND_INDICATORS
                : strcmp(arg, "display") == 0  ? COMMAND_DISPLAY
                                               : COMMAND_NONE;
      if (a->kind == COMMAND_NONE) fprintf(stderr, "%s: '%s' is not indicators or display\n", prog, arg);
      return a->kind != COMMAND_NONE;
    case 1:
      if (!example_parse_long(prog, a->kind == COMMAND_INDICATORS ? "indicators INSTANCE" : "display INSTANCE", arg, 1,
                              MAX_INSTANCE, &instance))
        return 0;
      a->instance = (unsigned)instance;
      return 1;
    default: example_unexpected(prog, arg); return 0;
  }
}

int command_complete(const char* prog, const struct command_args* a) {
  const int indicators = a->kind == COMMAND_INDICATORS;
  if (a->kind == COMMAND_NONE) fprintf(stderr, "%s: no command: indicators or display\n", prog);
  else if (a->instance == 0)
    fprintf(stderr, "%s: %s: no INSTANCE (1..8)\n", prog, indicators ? "indicators" : "display");
  else if (indicators ? !a->have_on : !a->have_set)
    fprintf(stderr, "%s: %s needs %s\n", prog, indicators ? "indicators" : "display",
            indicators ? "--on LIST (the indicators to light; none: all off)" : "--set P=V,... (the parameters)");
  else if (indicators ? a->have_set : a->have_on)
    fprintf(stderr, "%s: %s is for %s\n", prog, indicators ? "--set" : "--on", indicators ? "display" : "indicators");
  else return 1;
  return 0;
}

void command_text(char* out, size_t size, const struct command_args* a) {
  size_t n = 0;
  if (a->kind == COMMAND_INDICATORS) {
    n = (size_t)snprintf(out, size, "indicators.%u indicators=0x%016llx (on:", a->instance, a->indicators);
    for (int i = 0; i < MAX_INDICATOR && n < size; i++)
      if (a->indicators & (1ULL << i)) n += (size_t)snprintf(out + n, size - n, " %d", i + 1);
    if (n < size) snprintf(out + n, size - n, "%s)", a->indicators == 0 ? " none" : "");
    return;
  }
  n = (size_t)snprintf(out, size, "display.%u parameters=", a->instance);
  for (int i = 0; i < PARAMETERS && n < size; i++)
    n += (size_t)snprintf(out + n, size - n, "%s%d", i ? "," : "", a->parameters[i]);
}
