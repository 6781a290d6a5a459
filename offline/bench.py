#!/usr/bin/env python3
"""
Run a benchmark and print its figures as JSON.

Each benchmark measures its subject against a baseline in the same run (a ratio, not
an absolute time that depends on the machine) and states its goals beside the figures.

    python offline/bench.py sim        # batch simulation vs real time
    python offline/bench.py convert    # bag conversion vs a bare rosbags pass
    python offline/bench.py forecast   # predictor latency vs a naive loop
    python offline/bench.py soak       # concurrent what-if clients against the node
    python offline/bench.py outage     # /diagnostics while a source pauses, dies, doubles
    python offline/bench.py departure  # the departure WARN: an effect switched on mid-run
    python offline/bench.py scale      # 1 vs 2 training processes, 10x data, 1 vs 2 workers
    python offline/bench.py launch     # a study's trainings forked vs one process each
    python offline/bench.py --quick SUITE   # the suite in seconds to minutes (CI): each
                                            # module's QUICK options, before your own
"""

import argparse
import importlib
import json
import sys

# Each suite is a module in offline/benchmarks with add_arguments(parser) and
# run(args) -> dict; it is imported only when chosen, so one suite's heavy
# dependencies never slow another.
SUITES = {
    'sim': ('benchmarks.sim', 'paper-sized batch simulation (96 runs x 1 h)'),
    'convert': ('benchmarks.convert', 'bag-to-dataset conversion throughput'),
    'forecast': ('benchmarks.forecast', '900-step forecast latency and throughput'),
    'soak': ('benchmarks.soak', 'service soak: every request answered, forecasts flowing'),
    'outage': ('benchmarks.outage', 'health under outages: time to ERROR and to recovery, '
                                    'per vessel, in either clock mode'),
    'departure': ('benchmarks.departure', 'the departure WARN through the nodes: an '
                                          'unmodelled effect switched on mid-run'),
    'scale': ('benchmarks.scale', 'scaling out: training processes and memory, '
                                  'conversion workers'),
    'launch': ('benchmarks.launch', "a study's trainings forked from the launcher vs one "
                                    'process each'),
    'diagnose': ('benchmarks.diagnose', 'a blind diagnosis of ten hours of recordings'),
}


def main(argv=None) -> int:
    """Parse the command line, run one suite, print its JSON; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--quick', action='store_true',
                        help="a short run of the suite (its module's QUICK options; any "
                             'given after the suite still apply): it runs end to end, for CI')
    sub = parser.add_subparsers(dest='suite', required=True, metavar='SUITE')
    modules = {}
    for name, (module_name, help_text) in SUITES.items():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name != module_name:
                raise
            continue
        modules[name] = module
        module.add_arguments(sub.add_parser(name, help=help_text, description=help_text))
    args = parser.parse_args(argv)
    if args.quick:   # the suite's short options first: the user's, after them, win
        argv = list(sys.argv[1:] if argv is None else argv)
        at = argv.index(args.suite) + 1
        args = parser.parse_args(argv[:at] + list(modules[args.suite].QUICK) + argv[at:])
    result = modules[args.suite].run(args)
    json.dump(result, sys.stdout, indent=2)
    sys.stdout.write('\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
