"""The tasks a scenario may name (``task = ...``), as rules the schema and the checks read: never
``if task == ...``. What an episode builds for each is :mod:`pickdemo.runtime.tasks`; each task's
own checks are :data:`pickdemo.scenario.checks.TASK_CHECKS`."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TaskRules:
    """What a task asks of its scenario."""

    name: str
    runs_episodes: bool  # `run` and `bench` run it (else only `perceive` looks at its scenes)
    one_target: bool  # exactly one object has target = true, and it is not static (it is lifted)
    picks_every_object: bool  # every object it lists is picked (else its targets)
    places_target: bool  # its target is put down at the place (drawn per seed, kept off a belt)
    draws_round: bool  # it draws a round of objects per seed ([clear]) and drops them into a tray


#: The tasks, by name.
TASK_RULES: dict[str, TaskRules] = {
    rules.name: rules
    for rules in (
        TaskRules("pick", runs_episodes=True, one_target=True, picks_every_object=False, places_target=True,
                  draws_round=False),
        TaskRules("perceive", runs_episodes=False, one_target=False, picks_every_object=False, places_target=False,
                  draws_round=False),
        TaskRules("clear", runs_episodes=True, one_target=False, picks_every_object=True, places_target=False,
                  draws_round=True),
    )
}  # fmt: skip
