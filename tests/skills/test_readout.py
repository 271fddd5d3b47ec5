"""A finished pick is at rest only once the joint commands sent have caught up with where its motion
ended: the next controller (a clear round's next pick) starts from rest there, and a line the rate
limiter held back goes on being sent after the motion finished (measured: a faster carry's last
line, 0.3 rad/s still on the base joint at the release, and the next pick's first tick asked it for
48 rad/s^2: the robot's reflex stopped it)."""

from types import SimpleNamespace

import numpy as np

from pickdemo.skills.pick.params import MachineParams, State
from pickdemo.skills.pick.readout import MachineReadout


def _machine(state: State, dq: list[float], *, end_at_rest: bool = True, braked: bool = False) -> MachineReadout:
    m = MachineReadout.__new__(MachineReadout)
    m.state = state
    m.p = MachineParams(end_at_rest=end_at_rest)
    m.arm = SimpleNamespace(limiter=SimpleNamespace(dq=np.asarray(dq)), braked=braked)
    return m


def test_a_done_pick_is_at_rest_only_once_the_commands_sent_have_stopped() -> None:
    assert not _machine(State.DONE, [0.3, 0.0]).at_rest
    assert _machine(State.DONE, [0.0, 0.0]).at_rest


def test_a_failed_pick_is_at_rest_braked_or_with_the_commands_stopped() -> None:
    assert not _machine(State.FAILED, [0.3, 0.0]).at_rest
    assert _machine(State.FAILED, [0.0, 0.0], braked=True).at_rest
    assert not _machine(State.FAILED, [0.3, 0.0], braked=True).at_rest  # (braked, the commands still catching up)
    assert not _machine(State.FAILED, [0.3, 0.0], end_at_rest=False).at_rest
    assert _machine(State.FAILED, [0.0, 0.0], end_at_rest=False).at_rest
    assert not _machine(State.LIFT, [0.0, 0.0]).at_rest
