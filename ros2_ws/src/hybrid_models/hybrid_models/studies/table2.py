"""
Baier et al.'s Table 2 as a study: the trainings it needs, the paper's claims, the report.

``plan`` lists QLag, the LSTM baseline and every hybrid (physical model x 1P/2P) with the
package's configs; ``run_training`` trains one of them resumably; ``check_claims`` and
``report`` turn the evaluation's results.json into the findings and REPORT.md. The
``reproduce_table2`` program (hybrid_models.cli.reproduce_table2) runs them in order.
"""

import hashlib
import json
import math
from pathlib import Path

from hybrid_models.checkpoint import CheckpointError, read_header
from hybrid_models.data import dataset_hash
from hybrid_models.evaluation import smallest_threshold
from hybrid_models.training.config import config_dir
from hybrid_models.training.jobs import train_job

PHYSICAL = ['min', 'pro', 'lin', 'hyd', 'min+lin', 'pro+lin', 'min+hyd', 'pro+hyd']
PAPER_NAME = {'min': 'Min', 'pro': 'Pro', 'lin': 'Lin', 'hyd': 'Hyd', 'min+lin': 'Min+Lin',
              'pro+lin': 'Pro+Lin', 'min+hyd': 'Min+Hyd', 'pro+hyd': 'Pro+Hyd'}
THRESHOLD = 0.15


def plan(smoke: bool) -> list[tuple[str, Path, list[str]]]:
    """(label, config, overrides) of every training."""
    def cfg(name):
        return config_dir() / ('smoke.yaml' if smoke else name)
    jobs = [('QLag', cfg('qlag.yaml'), ['model.kind=qlag'] if smoke else []),
            ('LSTM', cfg('lstm.yaml'), ['model.kind=lstm', 'training.phases=[{kind: '
                                        'multistep, max_epochs: 3, patience: 2, lr: 0.003}]']
             if smoke else [])]
    for phys in PHYSICAL:
        for phases in ('1P', '2P'):
            over = [f'model.physical.kind={phys}']
            if smoke and phases == '1P':
                over.append('training.phases=[{kind: multistep, max_epochs: 3, patience: 2, '
                            'lr: 0.003}]')
            jobs.append((f'{PAPER_NAME[phys]}-{phases}',
                         cfg(f'hybrid_{phases.lower()}.yaml'), over))
    return jobs


def run_training(label, config, overrides, args, work: Path, limit_min: float) -> dict:
    """Train one model in a subprocess (resumable); return its summary."""
    threads = max(1, args.threads // args.jobs)
    sets = overrides + [f'training.threads={threads}', f'dataset={args.dataset}', 'name=' +
                        label]
    if config.name != 'qlag.yaml' and not args.smoke:
        sets.append(f'training.time_limit_minutes={limit_min:.1f}')
    return train_job(label, config, sets, work / label)


def evaluation_fingerprint(model_files, dataset, eval_args) -> str:
    """
    Return what an evaluation's figures depend on, as one digest.

    The bytes of every model evaluated, the dataset (``data.dataset_hash``: its manifest
    and run files) and the evaluation's arguments: equal digests give equal figures, so a
    study run again over kept trainings keeps its evaluation too.
    """
    digest = hashlib.sha256()
    for path in model_files:
        digest.update(Path(path).read_bytes())
    digest.update(dataset_hash(dataset).encode())
    digest.update(json.dumps([str(a) for a in eval_args]).encode())
    return digest.hexdigest()


def kept_evaluation(results: Path, fingerprint: str) -> bool:
    """Return whether ``results`` (a results.json) holds the evaluation of ``fingerprint``."""
    try:
        return json.loads(Path(results).read_text()).get('evaluation_fingerprint') == fingerprint
    except (OSError, ValueError):
        return False


def val_score(run_dir: Path) -> float:
    """Return the validation multistep score stored in a trained model (inf if none)."""
    try:
        val = read_header(Path(run_dir) / 'model.safetensors').get('val') or {}
    except (CheckpointError, FileNotFoundError):
        return float('inf')
    score = val.get('score')
    return float('inf') if score is None else float(score)


def _row(result, label):
    return next((r for r in result['rows'] if r['label'] == label), None)


def _traj(row):
    return None if row is None else row['metrics']['trajectory']['mean']


def check_claims(result: dict, best: str, bound_label: str) -> dict:
    """Check the three findings the project wants to show; return the evidence."""
    claims = {}
    pairs = {}
    for phys in PAPER_NAME.values():
        one, two = _traj(_row(result, f'{phys}-1P')), _traj(_row(result, f'{phys}-2P'))
        pairs[phys] = {'1P': one, '2P': two,
                       '2P_better': two is not None and (one is None or two < one)}
    claims['2P_beats_1P'] = {'holds': all(p['2P_better'] for p in pairs.values()),
                             'per_model': pairs}
    lstm, qlag, hyb = (_traj(_row(result, x)) for x in ('LSTM', 'QLag', best))
    claims['best_hybrid_vs_baselines'] = {
        'best_2p': best, 'best_2p_trajectory': hyb, 'lstm': lstm, 'qlag': qlag,
        'hybrid_le_lstm': None if None in (hyb, lstm) else hyb <= lstm,
        'both_le_half_qlag': None if None in (hyb, lstm) else (
            qlag is None or max(hyb, lstm) <= 0.5 * qlag)}
    sweep = result.get('threshold_sweep', {}).get('rows', [])
    free = next((r for r in sweep if r['relative_threshold'] is None), None)
    within = {}
    for r in sweep:
        t = r['relative_threshold']
        if t is None or free is None:
            continue
        ratios = {s: (None if r['rmse'][s] is None or not free['rmse'][s]
                      else r['rmse'][s] / free['rmse'][s]) for s in free['rmse']}
        within[str(t)] = {'ratios': ratios, 'all_within_5pct': all(
            x is not None and x <= 1.05 for x in ratios.values())}
    smallest = None if free is None else smallest_threshold(
        [r for r in sweep if (r['relative_threshold'] or 0.0) <= THRESHOLD], free['rmse'], 0.05)
    claims['threshold_costs_no_accuracy'] = {
        'holds': smallest is not None, 'smallest_threshold_within_5pct': smallest,
        'per_threshold': within}
    trained = _row(result, bound_label)
    at15 = next((r for r in sweep if r['relative_threshold'] == THRESHOLD), None)
    claims['bound_placement_at_15pct'] = {
        'inference_only': None if at15 is None else {
            'rmse': at15['rmse'], 'trajectory': at15['trajectory']['mean'],
            'ci95': at15['trajectory']['ci95']},
        'during_training': None if trained is None else {
            'rmse': trained['metrics']['rmse'], 'trajectory': _traj(trained),
            'ci95': trained['metrics']['trajectory']['ci95']}}
    return claims


def _m(x) -> str:
    return 'diverged' if x is None else f'{x:.1f}'


def _placement(p: dict) -> str:
    inf, trn = p['inference_only'], p['during_training']
    if inf is None or trn is None:
        return 'not available'
    a, b = inf['trajectory'] or math.inf, trn['trajectory'] or math.inf
    if abs(a - b) <= max(inf.get('ci95') or 0.0, trn.get('ci95') or 0.0):
        verdict = 'no difference beyond the 95 % CI'
    else:
        verdict = 'better: ' + ('during training' if b < a else 'at inference only')
    return (f"at inference only {_m(inf['trajectory'])} m, during training "
            f"{_m(trn['trajectory'])} m; {verdict}")


def report(result: dict, args) -> str:
    """Write REPORT.md: protocol, table, findings, training cost."""
    c = result['claims']
    proto = result['protocol']
    lines = ['# Table 2 reproduction', '',
             f"Dataset `{result['dataset']['path']}` (sha256 "
             f"`{result['dataset']['sha256'][:12]}`), {len(result['dataset']['runs'])} test "
             f"runs, {proto['n_forecasts']} forecasts of {proto['horizon']} steps every "
             f"{proto['stride']} s after a {proto['window']}-sample window of measured data; "
             f"targets: {proto['target']} states. Models are selected and stopped on the "
             f"validation runs only. Total time {result['total_minutes']} min.", '',
             (args.out / 'table.md').read_text(), '## Findings', '']
    two = c['2P_beats_1P']
    lines.append(f"1. 2P beats 1P on trajectory error for every physical model: "
                 f"**{two['holds']}**")
    for phys, p in two['per_model'].items():
        lines.append(f"   - {phys}: 1P {_m(p['1P'])} m, 2P {_m(p['2P'])} m")
    b = c['best_hybrid_vs_baselines']
    lines.append(f"2. Best 2P hybrid by validation: {b['best_2p']} "
                 f"({_m(b['best_2p_trajectory'])} m); LSTM {_m(b['lstm'])} m; QLag "
                 f"{_m(b['qlag'])} m. Hybrid <= LSTM: **{b['hybrid_le_lstm']}**; both <= "
                 f"0.5 x QLag: **{b['both_le_half_qlag']}**")
    t = c['threshold_costs_no_accuracy']
    lines.append(f"3. A relative threshold <= 15 % keeps every per-state RMSE of "
                 f"{b['best_2p']} within 5 % of the unconstrained model: **{t['holds']}** "
                 f"(smallest such threshold: {t['smallest_threshold_within_5pct']})")
    for thr, w in t['per_threshold'].items():
        ratios = ', '.join(f'{k} {v:.3f}' if v is not None else f'{k} -'
                           for k, v in w['ratios'].items())
        lines.append(f'   - T = {float(thr):.3g}: RMSE / unconstrained: {ratios}')
    lines.append('4. Bound placement at a 15 % threshold (trajectory error): '
                 + _placement(c['bound_placement_at_15pct']))
    lines += ['', '## Training cost', '', '| model | train time [min] | epochs | best epoch '
              '| stop |', '|---|---|---|---|---|']
    for row in result['rows']:
        if row.get('train_seconds') is not None:
            lines.append(f"| {row['label']} | {row['train_seconds'] / 60:.1f} | "
                         f"{row.get('epochs')} | {row.get('best_epoch')} | "
                         f"{row.get('stop_reason', '')} |")
    lines += ['', 'Figures: states_over_time.png, trajectories.png, '
              'trajectory_error_per_minute.png, rmse_vs_threshold.png. Every number: '
              'results.json.', '']
    return '\n'.join(lines)

