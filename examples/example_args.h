/* Checked numbers for the examples' command lines (C, so the C and the C++ examples share it).
 * Every refusal names the program, the option and the text, on stderr; the caller then prints its
 * usage and exits EXAMPLE_EXIT_USAGE. */
#ifndef OEGW_EXAMPLE_ARGS_H
#define OEGW_EXAMPLE_ARGS_H

#include <getopt.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Exit statuses shared by the examples (docs/guides/dds-lcm.md#the-examples). */
enum {
  EXAMPLE_EXIT_OK = 0,
  EXAMPLE_EXIT_SETUP = 1,     /* the transport could not be opened */
  EXAMPLE_EXIT_USAGE = 2,     /* the command line was refused */
  EXAMPLE_EXIT_INCOMPLETE = 3 /* the timeout came before what was asked for, or a message did not decode */
};

/* TEXT (the value of OPTION) as a whole number in [min, max], decimal or 0x-hex, nothing after it.
 * Returns 1, or prints "PROG: OPTION: 'TEXT' is not a whole number from MIN to MAX" and returns 0. */
int example_parse_long(const char* prog, const char* option, const char* text, long min, long max, long* out);

/* TEXT as a number of seconds, more than 0 and at most a day. */
int example_parse_seconds(const char* prog, const char* option, const char* text, double* out);

/* "PROG: unexpected argument 'ARG'" for positional arguments a program does not take. */
void example_unexpected(const char* prog, const char* arg);

/* One option C (getopt_long's value) with its VALUE (NULL for a flag) into CTX: 1 taken, 0 refused
 * (said why on stderr). For positional arguments C is their index from 0. */
typedef int (*example_take_fn)(const char* prog, int c, const char* value, void* ctx);
typedef void (*example_usage_fn)(FILE* to, const char* prog);

/* The whole command line with getopt_long and LONGS (long options only): every option to TAKE,
 * every positional argument to POSITIONAL (NULL: the program takes none), 'h' prints USAGE on
 * stdout. Returns -1 to go on, or the status to exit with: 0 after --help, EXAMPLE_EXIT_USAGE after
 * an unknown option, a missing or refused value or an unexpected argument (the reason and the
 * usage on stderr). */
int example_parse_options(int argc, char** argv, const struct option* longs, example_take_fn take,
                          example_take_fn positional, example_usage_fn usage, void* ctx);

/* The program's name as it was started, without the folder (for messages). */
const char* example_prog(const char* argv0);

#ifdef __cplusplus
}
#endif

#endif
