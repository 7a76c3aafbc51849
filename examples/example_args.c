#include "example_args.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int example_parse_long(const char* prog, const char* option, const char* text, long min, long max, long* out) {
  char* end = NULL;
  errno = 0;
  const long v = strtol(text, &end, 0);
  if (text[0] == 0 || *end != 0 || errno == ERANGE || v < min || v > max) {
    fprintf(stderr, "%s: %s: '%s' is not a whole number from %ld to %ld\n", prog, option, text, min, max);
    return 0;
  }
  *out = v;
  return 1;
}

int example_parse_seconds(const char* prog, const char* option, const char* text, double* out) {
  char* end = NULL;
  errno = 0;
  const double v = strtod(text, &end);
  if (text[0] == 0 || *end != 0 || errno == ERANGE || !isfinite(v) || v <= 0 || v > 86400) {
    fprintf(stderr, "%s: %s: '%s' is not a number of seconds above 0 and at most 86400\n", prog, option, text);
    return 0;
  }
  *out = v;
  return 1;
}

void example_unexpected(const char* prog, const char* arg) {
  fprintf(stderr, "%s: unexpected argument '%s'\n", prog, arg);
}

const char* example_prog(const char* argv0) {
  const char* slash = strrchr(argv0, '/');
  return slash != NULL ? slash + 1 : argv0;
}

int example_parse_options(int argc, char** argv, const struct option* longs, example_take_fn take,
                          example_take_fn positional, example_usage_fn usage, void* ctx) {
  const char* prog = example_prog(argv[0]);
  int c = 0, ok = 1;
  while (ok && (c = getopt_long(argc, argv, "", longs, NULL)) != -1) {
    if (c == 'h') {
      usage(stdout, prog);
      return EXAMPLE_EXIT_OK;
    }
    ok = c != '?' && take(prog, c, optarg, ctx); /* '?': getopt said what is wrong */
  }
  for (int i = optind; ok && i < argc; i++) {
    ok = positional != NULL && positional(prog, i - optind, argv[i], ctx);
    if (positional == NULL) example_unexpected(prog, argv[i]);
  }
  if (ok) return -1;
  usage(stderr, prog);
  return EXAMPLE_EXIT_USAGE;
}
