"""The diagnosis' stage clock counts each second once: a stage's time excludes the stages inside it."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from diagnosis.stages import StageClock  # noqa: E402


def test_nested_stages_are_exclusive_and_add_up() -> None:
    t = [0.0]
    clock = StageClock(now=lambda: t[0])
    with clock.stage("ranking"):
        t[0] += 1.0                       # ranking's own
        with clock.stage("local refits"):
            t[0] += 5.0
        t[0] += 0.5                       # ranking's own again
        with clock.stage("pairs"):
            t[0] += 2.0
            with clock.stage("local refits"):   # a stage entered twice adds up
                t[0] += 3.0
    t[0] += 100.0                         # outside every stage: not counted
    assert clock.seconds == pytest.approx({"ranking": 1.5, "local refits": 8.0, "pairs": 2.0})
    assert sum(clock.seconds.values()) == pytest.approx(11.5)


def test_a_stage_that_raises_is_still_counted() -> None:
    t = [0.0]
    clock = StageClock(now=lambda: t[0])
    with pytest.raises(KeyboardInterrupt), clock.stage("refit"):
        t[0] += 2.0
        raise KeyboardInterrupt
    assert clock.seconds == {"refit": 2.0}
