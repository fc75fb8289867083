"""`studio bench stack`: the stack and MuJoCo alone take turns on the same ticks (issue 12)."""

from __future__ import annotations

import math

import pytest

from engine.bench import stack


@pytest.mark.slow  # G1 walks of 0.3 s and 1.1 s with their replays: ≈ 12 s with the robot's loading
def test_stack_and_mujoco_alone_replay_the_same_ticks_in_turns(monkeypatch):
    """A warm-up walk of 0.3 s (one short turn, reported apart), then 1.1 s in chunks of 0.5 s: three turns (the
    last one short); every tick is replayed once, the ratio is a ratio of two positive totals, and the replay used
    the commands of its own chunk."""
    replayed: list[int] = []
    original = stack._Replay.compute

    def compute(self, state):  # noqa: ANN001, ANN202
        replayed.append(self.k)
        return original(self, state)

    monkeypatch.setattr(stack._Replay, "compute", compute)
    row = stack.run_stack("g1", seconds=1.1, warm_up_s=0.3)
    warm, ticks = round(0.3 / 0.002), round(1.1 / 0.002)
    assert row["sim_s"] == 1.1 and not row["fell"]
    assert len(replayed) == warm + ticks
    assert replayed[:warm] == list(range(warm)), "the warm-up walk is replayed in its own turn"
    assert row["warm_up_s"] == 0.3 and row["warm_up_stack_wall_s"] > 0 and row["warm_up_stack_over_mujoco"] > 0
    assert row["warm_up_fell"] is False
    replayed = replayed[warm:]
    chunk = round(stack.CHUNK_S / 0.002)
    assert replayed[:chunk] == list(range(chunk)) and replayed[chunk:2 * chunk] == list(range(chunk))
    assert replayed[2 * chunk:] == list(range(ticks - 2 * chunk))
    for key in ("mujoco_alone_wall_s", "stack_wall_s", "mujoco_alone_cpu_s", "stack_cpu_s"):
        assert row[key] > 0, key
    assert math.isclose(row["stack_over_mujoco"], row["stack_wall_s"] / row["mujoco_alone_wall_s"], rel_tol=0.02)
    assert row["stack_over_mujoco"] > 1.0  # the stack does the physics and more
