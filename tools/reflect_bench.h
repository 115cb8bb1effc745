/* reflect_bench.h - the `reflect bench` subcommand (tools/reflect_bench.c),
   linked into the reflect command with the Embree peer. */
#ifndef REFL_CLI_BENCH_H
#define REFL_CLI_BENCH_H

/* argv[1] is "bench"; returns the process exit status. */
int refl_cli_bench(int argc, char **argv);

#endif
