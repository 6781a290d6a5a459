r"""
The peer benchmark: other identification tools on our splits, windows and measures.

    python offline/peer_benchmark.py --study STUDY --out docs/results/peers/snuboat_heldout \\
        [--peer narx --peer sindy --peer deepsysid-lstm] [--seeds 5] [--work DIR]

STUDY is a finished ``offline/crossval.py`` study (our QLag, LSTM, hybrid and its
physics, trained and scored on the dataset's own split or on folds), or the output
directory of ``offline/reproduce_table3.py`` (the dataset's own split; --dataset where
it moved). Each peer (``narx``: SysIdentPy's NARX by FROLS; ``sindy``: PySINDy's
discrete-time SINDYc; ``deepsysid-lstm``: Baier et al.'s deepsysid LSTM with
initializer) is fitted on every fold's training runs, tuned on its validation runs and
forecasts its test windows (the study's window, horizon and stride), by its adapter in
offline/peers/ run with the bench-only environment's interpreter (``tools/setup.sh
bench``); its answers are scored with the study's measures against the study's truth,
pooled over folds (mean ± sd over seeds for a stochastic peer). Writes OUT/results.json
(every number, each peer's grid, choice and fit time) and OUT/table.md (the peers beside
the study's rows). A peer whose answer to the same problem exists is kept (resumable).
Run from the repository root. Exit codes: 0 done, 1 a peer or an input failed (one
line), 2 bad arguments.
"""

import argparse
from pathlib import Path
import sys

from hybrid_models.studies.peers import PEERS, PeerStudyError, study


def main(argv=None) -> int:
    """Run the peers on a study; return the exit code."""
    parser = argparse.ArgumentParser(prog='peer_benchmark', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--study', type=Path,
                        help='a finished crossval or Table 3 study (its results.json); '
                             "without it, --dataset's own split and its vehicle's protocol, "
                             'the peers alone')
    parser.add_argument('--out', type=Path, required=True, help='results directory')
    parser.add_argument('--dataset', type=Path,
                        help="a Table 3 study's dataset (default: the path it names), or the "
                             'dataset of the peers alone')
    parser.add_argument('--peer', action='append', choices=sorted(PEERS),
                        help='a peer to run (repeatable; default all)')
    parser.add_argument('--seeds', type=int, default=5,
                        help='seeds of a stochastic peer, 0..N-1 (default 5)')
    parser.add_argument('--work', type=Path, help='problems and answers (default OUT/work)')
    parser.add_argument('--bench-python', type=Path, default=Path('.venv-bench/bin/python'),
                        help='the bench environment interpreter (default .venv-bench)')
    parser.add_argument('--repo', type=Path, default=Path('.'),
                        help='the repository root holding offline/peers (default .)')
    parser.add_argument('--title', help='the dataset as the table names it')
    parser.add_argument('--peer-option', action='append', default=[], metavar='PEER=ARGS',
                        help="arguments for one peer's adapter, e.g. "
                             "'deepsysid-lstm=--epochs-scale 0.25' (repeatable)")
    parser.add_argument('--quick', action='store_true',
                        help="each peer's documented defaults only, no grid (a dry run)")
    args = parser.parse_args(argv)
    if args.study is None and args.dataset is None:
        parser.error('give --study, or --dataset for the peers alone')
    if args.seeds < 1:
        parser.error('--seeds must be at least 1')
    options = {}
    for text in args.peer_option:
        peer, sep, rest = text.partition('=')
        if not sep or peer not in PEERS:
            parser.error(f'--peer-option takes PEER=ARGS with PEER one of {sorted(PEERS)}')
        options.setdefault(peer, []).extend(rest.split())
    try:
        summary = study(args.study, args.out, args.peer or list(PEERS),
                        list(range(args.seeds)), args.work, args.bench_python.absolute(),
                        args.repo.resolve(), args.quick, args.title, options=options,
                        dataset=args.dataset)
    except (PeerStudyError, ValueError, OSError) as exc:
        print(f'peer_benchmark: error: {exc}', file=sys.stderr)
        return 1
    print((args.out / 'table.md').read_text())
    print(f"{len(summary['rows'])} rows: {args.out / 'results.json'}", file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
