"""Whether the robot, told what its target looks like (not where it is), can tell it from the other
objects: a scenario whose target another object looks the same as is refused (:func:`check_twins`,
called by :func:`~pickdemo.scenario.checks.check_scenario`). Pure: no simulator."""

from __future__ import annotations

from pickdemo.perception.unknown import height_tolerance_m
from pickdemo.scenario.base import ScenarioError
from pickdemo.scenario.objects import ObjectSpec
from pickdemo.scenario.schema import Scenario
from pickdemo.scenario.tasks import TASK_RULES

#: Two objects whose sizes differ by no more than this (m, each dimension) and colours by no more than
#: ``TWIN_COLOUR`` (each channel, 0-1) look the same to the robot.
TWIN_SIZE_M = 0.003
TWIN_COLOUR = 0.08
#: A target told only its rough size (a mesh, a cylinder lying) is told apart by its height
#: (:func:`~pickdemo.perception.unknown.height_tolerance_m`), then by its footprint's sides: another
#: object as tall, each side within this factor, looks the same.
TWIN_FOOTPRINT_FACTOR = 1.5


def _size_ranges(obj: ObjectSpec) -> list[tuple[float, float]]:
    """Per dimension, the sizes it may have (m): a box's footprint sides sorted (a box turned a
    quarter is the same box), then its height; a cylinder's diameter and height."""
    ranges = list(obj.size_range) if obj.size_range is not None else [(s, s) for s in obj.size or ()]
    if obj.shape == "box" and len(ranges) == 3:
        ranges = sorted(ranges[:2]) + ranges[2:]
    return ranges


def _looks_the_same(a: ObjectSpec, b: ObjectSpec) -> bool:
    """Whether two objects may look the same to the robot, told only what its target looks like: the
    same shape, sizes within ``TWIN_SIZE_M`` (ranges that overlap), colours within ``TWIN_COLOUR``
    each channel; meshes: the same file at the same scales."""
    if a.shape != b.shape:
        return False
    if a.shape == "mesh":
        return a.urdf is not None and a.urdf == b.urdf and a.scales == b.scales
    sa, sb = _size_ranges(a), _size_ranges(b)
    if len(sa) != len(sb) or any(lo1 > hi2 + TWIN_SIZE_M or lo2 > hi1 + TWIN_SIZE_M
                                 for (lo1, hi1), (lo2, hi2) in zip(sa, sb, strict=True)):  # fmt: skip
        return False
    if a.color is None or b.color is None:
        return False
    return max(abs(x - y) for x, y in zip(a.color, b.color, strict=True)) <= TWIN_COLOUR


def _rough_sizes(obj: ObjectSpec) -> list[tuple[float, float, float]] | None:
    """Its height and its footprint's longer and shorter side as it stands, at its smallest and its
    largest (m); None for a mesh drawn from several files (not known before the seed)."""
    if obj.shape == "mesh":
        if obj.urdf is None:
            return None
        shapes = [obj.mesh_shape(obj.urdf, scale) for scale in obj.scales]
    else:
        ranges = obj.size_range or [(v, v) for v in obj.size or ()]
        shapes = [obj.shape_of_size(tuple(r[i] for r in ranges)) for i in (0, 1)]
    return [obj.rough_size(g) for g in shapes]


def _as_large(told: tuple[float, float, float], other: ObjectSpec) -> bool:
    """Whether ``other`` may look like a target told only its rough size ``told`` (height, longer and
    shorter side, m): as tall, within the height's tolerance, and each side of its footprint within
    ``TWIN_FOOTPRINT_FACTOR``."""
    b = _rough_sizes(other)
    if b is None:
        return False
    tol = height_tolerance_m(told[0])

    def near(i: int, factor: float, pad: float) -> bool:  # (the other's sizes span a range)
        lo_b, hi_b = min(s[i] for s in b), max(s[i] for s in b)
        return told[i] / factor - pad <= hi_b and lo_b <= told[i] * factor + pad

    return near(0, 1.0, tol) and near(1, TWIN_FOOTPRINT_FACTOR, 0.0) and near(2, TWIN_FOOTPRINT_FACTOR, 0.0)


def _check_told_size(target: ObjectSpec) -> None:
    """A rough size the robot could never match: the target's own height (every file at every scale it
    may have) outside the tolerance of the height stated, so no look would take it for the target."""
    told = target.rough_size_m
    assert told is not None
    if target.shape == "mesh":
        heights = [target.mesh_shape(f, s).height_m for f in target.urdf_files for s in target.scales]
    else:
        heights = [h for h, _, _ in _rough_sizes(target) or ()]
    tol = height_tolerance_m(told[0])
    if heights and not min(heights) - tol <= told[0] <= max(heights) + tol:
        lo, hi = f"{min(heights) * 1e3:.0f}", f"{max(heights) * 1e3:.0f}"
        raise ScenarioError(
            f"objects.{target.name}.rough_size_m: the target stands {lo if lo == hi else f'{lo}-{hi}'} "
            f"mm tall, not within {tol * 1e3:.0f} mm of the {told[0] * 1e3:.0f} mm stated: the robot would never take "
            "it for the target"
        )


def check_twins(sc: Scenario) -> None:
    """A pick whose target another object looks the same as is refused: the robot is told what its
    target looks like, not where it is, so it could carry the other (measured: 3 of 5 episodes did).
    A target nobody described is told at most its rough size: with none stated, it must be the only
    object; with one, no other as large."""
    if not TASK_RULES[sc.task].one_target:
        return
    target = sc.target
    if target.told_nothing and target.rough_size_m is not None:
        _check_told_size(target)
    for obj in sc.objects:
        if obj is target or obj.target:
            continue
        if target.told_nothing and target.rough_size_m is None:
            raise ScenarioError(
                f"objects.{target.name}: the robot is told nothing of this target (not its shape, size or colour), so "
                f"it cannot tell it from objects.{obj.name}; state its rough size (rough_size_m = [height, longer "
                "side, shorter side] in m) or leave it alone on the table"
            )
        if target.told_nothing and _as_large(target.rough_size_m, obj):  # type: ignore[arg-type]
            raise ScenarioError(
                f"objects.{obj.name}: about as large as the target objects.{target.name}, which the robot is told "
                "only by its rough size: it cannot tell them apart; make one differ in height (15 % or 1 cm)"
            )
        if _looks_the_same(target, obj):
            raise ScenarioError(
                f"objects.{obj.name}: looks the same as the target objects.{target.name} (its shape, size and "
                "colour): the robot, told only what its target looks like, cannot tell them apart; make one "
                "differ in colour or size"
            )
