"""ship_sim_node.command_gate: which external command is in force, and for how long."""

import pytest

from ship_sim_node.command_gate import CommandGate, CommandLimits

LIMITS = CommandLimits({'n': (0.0, 100.0), 'delta_port': (-0.5, 0.5),
                        'delta_stbd': (-0.5, 0.5)})


def test_a_command_holds_until_its_timeout_then_the_operator_resumes():
    gate = CommandGate(LIMITS, timeout_s=3.0)
    assert gate.active(0.0) is None
    assert gate.offer({'n': 50.0, 'delta_port': 0.1}, t=10.0) is None
    assert gate.active(12.0) == {'n': 50.0, 'delta_port': 0.1}
    assert gate.active(13.0) is not None and gate.active(13.5) is None


@pytest.mark.parametrize('command, reason', [
    ({'n': float('nan')}, 'not finite'),
    ({'n': float('inf')}, 'not finite'),
    ({'n': -1.0}, 'outside [0, 100]'),
    ({'n': 100.5}, 'outside [0, 100]'),
    ({'delta_stbd': -0.6}, 'outside [-0.5, 0.5]'),
    ({'thrust': 1.0}, 'unknown actuator'),
])
def test_bad_commands_are_rejected_and_the_last_good_one_holds(command, reason):
    gate = CommandGate(LIMITS, timeout_s=5.0)
    gate.offer({'n': 40.0}, t=0.0)
    assert reason in gate.offer(command, t=1.0)
    assert gate.active(2.0) == {'n': 40.0}
    assert (gate.accepted, gate.rejected) == (1, 1)


def test_a_rejected_command_does_not_extend_the_hold():
    gate = CommandGate(LIMITS, timeout_s=2.0)
    gate.offer({'n': 40.0}, t=0.0)
    gate.offer({'n': -1.0}, t=1.9)
    assert gate.active(2.5) is None


def test_limits_are_inclusive_and_clear_forgets():
    gate = CommandGate(LIMITS, timeout_s=1.0)
    assert gate.offer({'n': 0.0, 'delta_port': -0.5, 'delta_stbd': 0.5}, t=0.0) is None
    gate.clear()
    assert gate.active(0.0) is None
    with pytest.raises(ValueError):
        CommandGate(LIMITS, timeout_s=0.0)
