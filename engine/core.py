"""EngineCore: the engine's state machine, independent of processes and clocks.

It owns the robot model and the simulation, applies commands and produces events. The
engine process (:mod:`engine.process`) drives it in real time; tests and benchmarks drive it
directly, as fast as it goes.
"""

from __future__ import annotations

from typing import Callable

import mujoco
import numpy as np

from engine import protocol as msg
from engine.robot.config import RobotConfigError
from engine.robot.model import RobotModel, load_robot
from engine.sim import CONTROL_PERIOD_S, Simulation

FALL_RESET_DELAY_S = 1.5  # a fallen robot lies this long (so the user sees it) before the reset


class EngineCore:
    def __init__(self, robot: str, emit: Callable[[msg.Event], None]):
        self.emit = emit
        self.paused = False
        self.seq = 0
        self.robot: RobotModel
        self.sim: Simulation | None = None
        self._fallen_at_s: float | None = None
        self._kin_data: mujoco.MjData | None = None
        self.real_time_factor = 0.0
        self.load(robot)

    # ------------------------------------------------------------------ robot
    def load(self, name: str) -> None:
        self.robot = load_robot(name)
        if self.robot.config.simulated:
            self.sim = Simulation(self.robot)
            self._kin_data = None
        else:
            self.sim = None
            self._kin_data = mujoco.MjData(self.robot.mj_model)
            self._kin_data.qpos[:] = self.robot.mj_standing_qpos()
            mujoco.mj_kinematics(self.robot.mj_model, self._kin_data)
        self._fallen_at_s = None
        self.emit(msg.RobotLoaded(
            robot=self.robot.name, robot_kind=self.robot.kind, body_names=tuple(self.robot.body_names),
            joint_names=tuple(self.robot.joint_names), simulated=self.sim is not None,
        ))

    @property
    def running(self) -> bool:
        return self.sim is not None and not self.paused

    # ------------------------------------------------------------------ commands
    def handle(self, command: msg.Command) -> None:
        try:
            self._handle(command)
        except RobotConfigError as exc:
            self.emit(msg.Notice("error", str(exc)))
        except (ValueError, KeyError, TypeError) as exc:
            self.emit(msg.Notice("error", f"{command.kind}: {exc}"))

    def _handle(self, command: msg.Command) -> None:
        if isinstance(command, msg.Reset):
            self.reset()
        elif isinstance(command, msg.SetPaused):
            self.paused = bool(command.paused)
        elif isinstance(command, msg.ApplyPush):
            if self.sim is None:
                raise ValueError(f"{self.robot.name} is not simulated")
            force = np.asarray(command.force_n, dtype=float)
            if force.shape != (3,) or not np.all(np.isfinite(force)) or not np.isfinite(command.duration_s):
                raise ValueError("push needs a finite 3-vector force and duration")
            self.sim.push(force, max(0.0, float(command.duration_s)), command.body)
        elif isinstance(command, msg.SwitchRobot):
            if command.robot != self.robot.name:
                self.load(command.robot)
        else:
            raise ValueError(f"not supported by this engine yet: {command.kind}")

    def reset(self) -> None:
        if self.sim is not None:
            self.sim.reset()
        self._fallen_at_s = None

    # ------------------------------------------------------------------ stepping
    def tick(self) -> None:
        """One 500 Hz control tick (no-op when paused or not simulated)."""
        if not self.running:
            return
        assert self.sim is not None
        self.sim.step()
        if self.sim.fallen:
            if self._fallen_at_s is None:
                self._fallen_at_s = self.sim.time_s
                self.emit(msg.Notice("warning", f"{self.robot.name} fell at t = {self.sim.time_s:.2f} s; resetting"))
            elif self.sim.time_s - self._fallen_at_s > FALL_RESET_DELAY_S:
                self.reset()

    def frame(self) -> msg.Frame:
        self.seq += 1
        if self.sim is not None:
            pos, quat = self.sim.body_poses()
            joint_q = self.sim.joint_positions()
            t, fallen = self.sim.time_s, self.sim.fallen
        else:
            assert self._kin_data is not None
            pos, quat = self._kin_data.xpos[1:].copy(), self._kin_data.xquat[1:].copy()
            joint_q = self._kin_data.qpos[self.robot.mj_qpos_index].copy()
            t, fallen = 0.0, False
        return msg.Frame(
            seq=self.seq, sim_time_s=t, body_pos=pos.astype(np.float32), body_quat=quat.astype(np.float32),
            joint_q=joint_q.astype(np.float32), paused=self.paused, fallen=fallen,
            real_time_factor=self.real_time_factor,
        )


CONTROL_RATE_HZ = 1.0 / CONTROL_PERIOD_S
