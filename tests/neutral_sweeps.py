"""Closed-loop neutral sweeps of G1 and TALOS, tick by tick, for the bit-for-bit speed-reference tests."""

from __future__ import annotations

from collections.abc import Iterator

ROBOTS = ("g1", "talos")


def neutral_sweep_ticks(ticks: int, robots: tuple[str, ...] = ROBOTS) -> Iterator[tuple[int, object, object]]:
    """(k, controller, sim) after each of ``ticks`` simulation steps of each robot's neutral style walking the
    ``sweep`` command; a sweep that falls fails the test."""
    from engine.control.walking_controller import WalkingController
    from engine.gait.command_schedule import preset
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation

    for name in robots:
        robot = load_robot(name)
        style = load_style(styles_dir(name) / "neutral.json")
        controller = WalkingController(robot, style)
        sim = Simulation(robot, controller)
        schedule = preset("sweep", style.velocities)
        for k in range(ticks):
            controller.set_command(schedule(k * 0.002))
            sim.step()
            yield k, controller, sim
        assert not sim.fallen, f"{name}: the neutral sweep fell"
