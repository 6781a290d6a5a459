"""hybrid_predictor.skill: live scoring of matured forecasts and the departure detector."""

import numpy as np
import pytest

from hybrid_models.metrics import reported_steps
from hybrid_predictor.skill import POSITION, LiveSkill, Settings

DT = 1.0
H = 40
STEPS = reported_steps(H)            # 10, 20, 30, 40
SIGMA = 0.1                          # measurement scatter of u (m/s)
SPEED = 5.0                          # m/s, along x
Z90, Z50 = 1.645, 0.674              # normal quantiles of the synthetic bands
RADIUS90, RADIUS50 = 3.0, 1.5        # m
SETTINGS = Settings(forecast_period=1.0, window=60.0, min_samples=10, warn_coverage=0.5,
                    clear_coverage=0.7, sustain=20.0)


def tracker(**changes):
    settings = Settings(**{**SETTINGS.__dict__, **changes})
    return LiveSkill(['u', 'r'], STEPS, settings, DT)


def forecast(skill, t, x0, bands=True):
    """Offer a model forecast from t: u = SPEED, r = 0, the track along x."""
    k = np.arange(1, H + 1)
    states = np.column_stack([np.full(H, SPEED), np.zeros(H)])
    x, y = x0 + SPEED * k * DT, np.zeros(H)
    spread = np.array([[Z50 * SIGMA, Z50 * SIGMA], [Z90 * SIGMA, Z90 * SIGMA]])
    lower = states[None] - spread[:, None, :]
    upper = states[None] + spread[:, None, :]
    radius = np.array([np.full(H, RADIUS50), np.full(H, RADIUS90)])
    if not bands:
        return skill.add_forecast(t, states, x, y, band_note='no calibration')
    return skill.add_forecast(t, states, x, y, (0.5, 0.9), lower, upper, radius)


def run(skill, t_from, t_to, offset=0.0, seed=0, x=0.0, skip=(), bands=True, on_step=None,
        glitch=None):
    """
    Measure and forecast every second.

    ``offset`` adds to the vessel's u (m/s), ``glitch`` to the measured u only.
    """
    rng = np.random.default_rng(seed)
    for t in np.arange(t_from, t_to, DT):
        du = offset(t) if callable(offset) else offset
        u = SPEED + du + SIGMA * rng.standard_normal()
        x += u * DT
        measured = u + (0.0 if glitch is None else glitch(t))
        if t not in skip:
            skill.add_measurement(t, [measured, 0.0], x, 0.0)
        forecast(skill, t, x, bands)
        if on_step is not None:
            on_step(t, skill)
    return x


def test_noise_inside_the_band_raises_nothing_and_is_scored():
    skill = tracker()
    raised = []
    run(skill, 0.0, 500.0, on_step=lambda t, s: raised.append(s.departure().active))
    assert not any(raised)
    summary = skill.summary()
    for step in STEPS:
        u = summary[step]['u']
        assert u['n'] == 60                           # one per kept forecast in 60 s
        assert u['rmse'] == pytest.approx(SIGMA, rel=0.3)
        assert 0.75 <= u['coverage'][0.9] <= 1.0
        assert summary[step]['r']['rmse'] == 0.0
    assert skill.departure().judged


def test_a_sustained_offset_is_raised_naming_state_and_steps_then_cleared():
    skill = tracker()
    onset, end = 300.0, 700.0
    seen = {}

    def watch(t, s):
        d = s.departure()
        if d.active and 'raised' not in seen:
            seen['raised'], seen['affected'] = t, d.affected
            seen['message'] = s.describe(d)
        if 'raised' in seen and not d.active and 'cleared' not in seen:
            seen['cleared'] = t

    run(skill, 0.0, 1100.0, offset=lambda t: 1.0 if onset <= t < end else 0.0,
        on_step=watch)
    # The first matured step after the onset is out; half the window must be before
    # coverage < 0.5, then the sustain: 10 + 30 + 20 s for step 10.
    assert onset + 40.0 <= seen['raised'] <= onset + 10.0 + 30.0 + 20.0 + 5.0
    names = {name for name, _, _ in seen['affected']}
    assert 'u' in names and 'r' not in names
    assert all(cover < 0.5 for _, _, cover in seen['affected'])
    assert 'u at 10 s' in seen['message'] and 'departs from its model' in seen['message']
    # cleared once coverage recovers: after the offset, once 70 % of the window is good
    assert end < seen['cleared'] <= end + H + 0.7 * 60.0 + 5.0
    assert not skill.departure().active


def test_a_position_drift_is_named_as_position():
    skill = tracker()
    d = []
    run(skill, 0.0, 400.0, offset=lambda t: 0.3 if t >= 100 else 0.0,   # 0.3 m/s, 3 sigma
        on_step=lambda t, s: d.append(s.departure()))
    names = {name for name, _, _ in d[-1].affected}
    assert POSITION in names   # 0.3 m/s drifts 3 m in 10 s: outside the 3 m circle


def test_short_glitches_are_not_sustained():
    skill = tracker()
    raised, lowest = [], []

    def watch(t, s):
        raised.append(s.departure().active)
        cover = s.summary()[10]['u']['coverage']
        lowest.append(cover.get(0.9, 1.0))

    # a 20 s sensor glitch in u every 100 s: a third of the window's steps are out,
    # coverage dips below 0.9 but never below 0.5
    run(skill, 0.0, 800.0, glitch=lambda t: 1.0 if t % 100 < 20 else 0.0, on_step=watch)
    assert not any(raised)
    assert 0.5 < min(lowest[100:]) < 0.75


def test_forecasts_without_bands_are_scored_but_not_judged():
    skill = tracker()
    run(skill, 0.0, 400.0, offset=1.0, bands=False)
    d = skill.departure()
    assert not d.judged and not d.active
    assert 'no bands' in d.note and 'no calibration' in d.note
    u = skill.summary()[10]['u']
    assert u['n'] > 0 and u['rmse'] == pytest.approx(1.0, rel=0.2) and u['coverage'] == {}


def test_missing_samples_leave_steps_unscored():
    skill = tracker()
    skip = {float(t) for t in range(50, 400, 7)}
    run(skill, 0.0, 400.0, skip=skip)
    assert skill.counts['steps_missing'] > 0
    assert skill.counts['steps_scored'] > 0
    assert not skill.departure().active


def test_memory_is_bounded():
    skill = tracker()
    run(skill, 0.0, 300.0)
    assert len(skill.pending) <= H / SETTINGS.forecast_period + 2
    assert all(len(s.times) <= SETTINGS.window / SETTINGS.forecast_period + 1
               for s in skill.scores.values())


def test_only_one_forecast_per_period_is_kept_and_a_jump_back_resets():
    skill = tracker(forecast_period=10.0)
    kept = [forecast(skill, t, 0.0) for t in np.arange(0.0, 30.0, 1.0)]
    assert sum(kept) == 3
    assert forecast(skill, 5.0, 0.0)      # the clock went back: a new time line
    assert len(skill.pending) == 1


@pytest.mark.parametrize('bad', [dict(warn_coverage=0.8, clear_coverage=0.7),
                                 dict(window=0.0), dict(forecast_period=0.0)])
def test_inconsistent_settings_are_refused(bad):
    with pytest.raises(ValueError, match='skill'):
        tracker(**bad)


def test_a_missing_position_is_unknown_not_outside():
    skill = tracker()
    for t in np.arange(0.0, 200.0, DT):
        skill.add_measurement(t, [SPEED, 0.0], np.nan, np.nan)
        forecast(skill, t, SPEED * t)
    summary = skill.summary()[10]
    assert summary[POSITION]['n'] == 0 and summary[POSITION]['coverage'] == {}
    assert summary['u']['coverage'][0.9] == 1.0
    assert not skill.departure().active


def test_the_departure_is_a_warning_on_diagnostics_and_never_masks_an_error():
    from hybrid_predictor import health

    skill = tracker()
    run(skill, 0.0, 300.0, offset=lambda t: 1.0 if t >= 100 else 0.0)
    line = skill.describe(skill.departure())
    h = health.Health(silence_error=1.5, max_age=5.0, departure=line)
    h.record_input(299.0)
    h.record_forecast(299.0, 1.0, 0.0)
    level, message, _ = h.report(299.5, 299.0, 10, {})
    assert level == health.WARN and 'departs from its model' in message and 'u at' in message
    level, message, _ = h.report(305.0, 299.0, 10, {})   # stale for 6 s: ERROR first
    assert level == health.ERROR and message.startswith('inputs stale')
    assert 'departs from its model' in message
