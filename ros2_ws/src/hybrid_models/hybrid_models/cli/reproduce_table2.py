"""
Reproduce Baier et al.'s Table 2 on a dataset: train every model, evaluate, report.

    python offline/reproduce_table2.py --dataset DIR --out docs/results
    python offline/reproduce_table2.py --dataset DIR --out /tmp/t2 --smoke   # minutes

Trains QLag, the LSTM baseline and the hybrids {Min, Pro, Lin, Hyd, Min+Lin, Pro+Lin,
Min+Hyd, Pro+Hyd} x {1P, 2P} (configs in ros2_ws/src/hybrid_models/config), two at a
time on one thread each, every training capped so that the whole run fits
--budget-minutes. Then the best 2P hybrid BY VALIDATION error (never by test error) is
trained once more with its bound applied during training (relative threshold 15 %),
and everything is evaluated on the test runs: table.md, results.json, figures, and
REPORT.md with the paper's claims checked. Re-running the same command resumes: a
finished model is kept, a killed one continues from its last epoch, and the evaluation
is kept when its models, dataset and arguments are unchanged.
"""

import argparse
from concurrent.futures import ThreadPoolExecutor, as_completed
import json
from pathlib import Path
import sys
import time

from hybrid_models.cli.evaluate import main as evaluate
from hybrid_models.studies.table2 import (
    THRESHOLD,
    check_claims,
    evaluation_fingerprint,
    kept_evaluation,
    plan,
    report,
    run_training,
    val_score,
)


def main(argv=None) -> int:
    """Train all, evaluate, write the report; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--dataset', required=True, help='dataset directory')
    parser.add_argument('--out', type=Path, required=True, help='results directory')
    parser.add_argument('--work', type=Path, help='training directory (default OUT/runs)')
    parser.add_argument('--jobs', type=int, default=2, help='trainings at a time')
    parser.add_argument('--threads', type=int, default=2, help='cores to use in total')
    parser.add_argument('--budget-minutes', type=float, default=110,
                        help='wall-clock budget for all trainings (default 110)')
    parser.add_argument('--smoke', action='store_true', help='tiny configs (a dry run)')
    args = parser.parse_args(argv)
    work = args.work or args.out / 'runs'
    work.mkdir(parents=True, exist_ok=True)
    jobs = plan(args.smoke)
    # Trainings run `jobs` at a time; one more (the bound-in-training variant) follows.
    n_recurrent = len(jobs) - 1
    rounds = -(-n_recurrent // args.jobs) + 1
    limit = max(1.0, 0.92 * args.budget_minutes / rounds)
    print(f'{len(jobs)} trainings, {args.jobs} at a time, each capped at {limit:.1f} min',
          file=sys.stderr)
    t0 = time.monotonic()
    results = []
    with ThreadPoolExecutor(args.jobs) as pool:
        futures = [pool.submit(run_training, *job, args, work, limit) for job in jobs]
        for fut in as_completed(futures):
            res = fut.result()
            results.append(res)
            print(f"[{(time.monotonic() - t0) / 60:6.1f} min] {res['label']}: "
                  f"{res['status']}", file=sys.stderr)
    two_phase = [label for label, _, _ in jobs if label.endswith('-2P')]
    best = min(two_phase, key=lambda label: val_score(work / label))
    print(f'best 2P hybrid by validation: {best}', file=sys.stderr)
    best_cfg = next(job for job in jobs if job[0] == best)
    bound_label = f'{best}-T{int(THRESHOLD * 100)}train'
    results.append(run_training(bound_label, best_cfg[1], best_cfg[2] + [
        f'model.relative_threshold={THRESHOLD}', 'model.bound_in_training=true'],
        args, work, limit))
    labels = [job[0] for job in jobs] + [bound_label]
    dirs = [str(work / label) for label in labels if (work / label / 'model.safetensors')
            .exists()]
    shown = [label for label in labels if str(work / label) in dirs]
    eval_args = dirs + ['--dataset', str(args.dataset), '--out', str(args.out), '--labels',
                        *shown, '--sweep', best, '--physics-only', '--threads',
                        str(args.threads), '--plot', 'QLag', 'LSTM', best,
                        best.replace('-2P', '-1P')]
    if args.smoke:
        eval_args += ['--horizon', '100', '--window', '20', '--stride', '100']
    fingerprint = evaluation_fingerprint([Path(d) / 'model.safetensors' for d in dirs],
                                         args.dataset, eval_args)
    if kept_evaluation(args.out / 'results.json', fingerprint):
        print('evaluation kept: its models, dataset and arguments are unchanged',
              file=sys.stderr)
    else:
        rc = evaluate(eval_args)
        if rc != 0:
            print('reproduce_table2.py: error: evaluation failed', file=sys.stderr)
            return rc
    result = json.loads((args.out / 'results.json').read_text())
    result['evaluation_fingerprint'] = fingerprint
    result['trainings'] = sorted(results, key=lambda r: r['label'])
    result['best_2p_by_validation'] = best
    result['claims'] = check_claims(result, best, bound_label)
    result['total_minutes'] = round((time.monotonic() - t0) / 60, 1)
    (args.out / 'results.json').write_text(json.dumps(result, indent=2))
    (args.out / 'REPORT.md').write_text(report(result, args))
    print((args.out / 'REPORT.md').read_text())
    return 0


if __name__ == '__main__':
    sys.exit(main())
