"""The honest loop and named failures, held at run time: the controller is handed nothing of the
simulator or the scoring (a planted leak ends the episode in ``error``), and a bug is never read as
an episode that merely failed (its traceback in the result; the shared episode sets refuse it)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from pickdemo import load_scenario
from pickdemo.core.result import Stage
from pickdemo.perception import PerceptionError, TargetModel, estimate_pose
from pickdemo.runtime.episode import Episode, EpisodeOptions, run_episode
from pickdemo.runtime.honest import check_honest, truth_in
from pickdemo.runtime.tasks import PickTask
from tests.episodes import no_bugs


class _Part:
    def __init__(self, **kw: object) -> None:
        self.__dict__.update(kw)


class _Slotted:
    __slots__ = ("held",)

    def __init__(self, held: object) -> None:
        self.held = held


class _World:
    """Stands for an object of the episode's runtime (a World, a referee) in the pure tests."""

    def tick(self) -> None: ...


_World.__module__ = "pickdemo.runtime.world"


def test_truth_in_finds_a_simulator_object_wherever_it_is_held() -> None:
    truth = _World()

    def closure() -> object:
        return truth

    def default(x: object = truth) -> object:
        return x

    places = {
        "an attribute": _Part(world=truth),
        "a list in a part": _Part(parts=[1, _Part(deep={"k": (truth,)})]),
        "a closure": _Part(fn=closure),
        "a default": _Part(fn=default),
        "a bound method": _Part(on_end=truth.tick),
        "a partial": _Part(fn=functools.partial(print, truth)),
        "a dict's key": _Part(seen={truth: 1}),
        "a slot": _Slotted(truth),
    }
    for where, holder in places.items():
        found = truth_in(holder)
        assert found is not None and "pickdemo.runtime.world._World" in found, where
        with pytest.raises(AssertionError, match="what a real robot has not"):
            check_honest(holder)
    assert truth_in(_Part(a=np.zeros(3), b=[1.0, "x"], c={"k": (None,)})) is None


@pytest.mark.sim
def test_a_controller_handed_the_world_ends_its_episode_in_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """A harness that hands the controller the simulator's world is a bug: the episode ends in
    ``error`` with the leak's path and a traceback, and the episode sets of the tests refuse it."""
    build = PickTask.controller

    def leaky(self, scenario, world, told, referee, open_loop, common):  # noqa: ANN001, ANN202
        controller = build(self, scenario, world, told, referee, open_loop, common)
        controller.chooser.world = world  # planted: deep in one of its parts
        return controller

    monkeypatch.setattr(PickTask, "controller", leaky)
    result = run_episode(load_scenario("pick_cube"), 0)
    assert not result.success and result.failure.stage is Stage.ERROR
    assert "TruthLeak" in result.failure.reason and "chooser.world" in result.failure.reason
    assert result.failure.is_bug and "check_honest" in result.failure.traceback
    assert "traceback" in result.to_dict()["failure"]
    with pytest.raises(AssertionError, match="TruthLeak"):
        no_bugs([result])


@pytest.mark.sim
def test_an_estimators_bug_ends_the_episode_in_error_with_its_traceback(monkeypatch: pytest.MonkeyPatch) -> None:
    """An estimator that raises anything but a PerceptionError has a bug: not a frame where the target
    was missed (the loop would look again and a rate over seeds would hide it)."""

    def buggy(frame, model):  # noqa: ANN001, ANN202
        return [1, 2][5]  # an IndexError, as a real bug would raise

    monkeypatch.setattr("pickdemo.runtime.tasks.resolve_estimator", lambda name: buggy)
    result = run_episode(load_scenario("pick_cube"), 0, options=EpisodeOptions(perception_method="mine:buggy"))
    assert result.failure.stage is Stage.ERROR and result.failure.reason.startswith("IndexError")
    assert "in buggy" in result.failure.traceback
    monkeypatch.undo()  # ... while a typed failure carries no traceback
    fine = run_episode(load_scenario("pick_cube"), 0, options=EpisodeOptions(perception_method="nonsense"))
    assert fine.failure.stage is Stage.PERCEPTION and not fine.failure.is_bug
    assert "traceback" not in fine.to_dict()["failure"]


@pytest.mark.sim
def test_the_papers_method_names_a_singular_fit_and_lets_a_bug_through(monkeypatch: pytest.MonkeyPatch) -> None:
    """A singular system (too little seen) is a named perception failure; any other exception inside
    the method is a bug and escapes as itself."""
    episode = Episode(load_scenario("pick_cube"), 0)
    episode.reset()
    frame = episode.world.cameras["camera"].take(episode.world.scene, None, None)
    model: TargetModel = episode.model
    episode.close()
    assert estimate_pose(frame, model).n_face_pixels > 0  # the frame is a good one

    def singular(*a, **k):  # noqa: ANN002, ANN003, ANN202
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr("pickdemo.perception.pipeline.fit_outline", singular)
    with pytest.raises(PerceptionError, match="degenerate fit"):
        estimate_pose(frame, model)

    def bug(*a, **k):  # noqa: ANN002, ANN003, ANN202
        raise IndexError("index 3 is out of bounds")

    monkeypatch.setattr("pickdemo.perception.pipeline.fit_outline", bug)
    with pytest.raises(IndexError):
        estimate_pose(frame, model)


def test_a_refusal_is_judged_against_the_truth(tmp_path) -> None:  # noqa: ANN001
    """A pick the grasp planner refused is scored on the truth: whether the object as drawn fits the
    open hand (then the refusal was not the object's: a neighbour, a fixture or the planner's)."""
    from pickdemo.core.result import Failure
    from pickdemo.runtime.referee import Referee, diagnose
    from pickdemo.runtime.world import World
    from pickdemo.scenario.load import builtin_scenario_dirs

    refused = Failure(Stage.GRASP_PLANNING, "no grasp")
    assert diagnose(refused, None, True) == "refused_fits_hand"
    assert diagnose(refused, None, False) == "refused_too_wide"
    assert diagnose(refused, None, None) == "not_committed"  # (a clear round's: not judged)
    assert diagnose(Failure(Stage.IK, "out of reach"), None, True) == "not_committed"
    text = next(d / "pick_mug.toml" for d in builtin_scenario_dirs()).read_text()
    verdicts = []
    for scale in ("0.8", "2.0"):  # the mug's body 66 mm across, then 164 mm: the open hand takes 75 mm
        f = tmp_path / f"mug_{scale}.toml"
        f.write_text(text.replace("scale = 0.8", f"scale = {scale}"))
        sc = load_scenario(f, check=False)
        verdicts.append(Referee(sc, World(sc, 0), sc.target.name).fits_hand())
    assert verdicts == [True, False]
