"""CPU per streamed frame of two versions of studio/robot_view.py, side by side (issue 14's soak).

    git archive main | tar -x -C /tmp/base
    PYTHONPATH=. python tools/stream_cpu_compare.py /tmp/base . --clients 8 --rounds 2

For each checkout (alternated ``--rounds`` times): a viser server with G1's view, ``--clients`` headless
clients (the soak bench's, decoding the stream), 300 frames in which every body moves, sent at 60 Hz.
Prints the CPU ms per frame of the view's update (the caller's thread) and of viser's event loop
(conversion and per-client sends), and the fewest frames a client saw.
"""

from __future__ import annotations

import argparse
import importlib.util
import threading
import time

import numpy as np
import viser

from engine import protocol as msg
from engine.robot.model import load_robot
from studio.bench_soak import _Client, _free_port, _thread_cpu_s

N_FRAMES = 300


def measure(root: str, n_clients: int) -> str:
    spec = importlib.util.spec_from_file_location("robot_view_under_test", f"{root}/studio/robot_view.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    server = viser.ViserServer(port=_free_port(), verbose=False)
    stop = threading.Event()
    try:
        model = load_robot("g1")
        names = tuple(model.mj_model.body(i).name for i in range(1, model.mj_model.nbody))
        view = module.RobotView(server)
        view.load("g1", names)
        pool = [_Client(f"ws://127.0.0.1:{server.get_port()}/", stop) for _ in range(n_clients)]
        for c in pool:
            c.start()
        while len(server.get_clients()) < n_clients:
            time.sleep(0.05)
        time.sleep(2.0)  # the scene's backlog is out
        rng = np.random.default_rng(0)
        pos = rng.normal(size=(len(names), 3))
        wxyz = rng.normal(size=(len(names), 4))
        wxyz /= np.linalg.norm(wxyz, axis=1, keepdims=True)
        cpu0, main0, seen0 = _thread_cpu_s(), time.thread_time(), [c.robot_frames for c in pool]
        for k in range(N_FRAMES):
            pos = pos + 0.005
            wxyz = wxyz + 0.001
            view.update(msg.Frame(k, k / 60, pos.copy(), wxyz.copy(), np.zeros(0), False, False, 1.0))
            time.sleep(1 / 60)
        time.sleep(1.0)
        cpu1, main1 = _thread_cpu_s(), time.thread_time()
        loop = "viser event loop + other"
        seen = [c.robot_frames - s for c, s in zip(pool, seen0)]
        return (f"{root}: clients {n_clients}: update {1e3 * (main1 - main0) / N_FRAMES:.2f} ms/frame, viser event loop "
                f"{1e3 * (cpu1[loop] - cpu0[loop]) / N_FRAMES:.2f} ms/frame, fewest frames a client saw "
                f"{min(seen) if seen else '-'} of {N_FRAMES}")
    finally:
        stop.set()
        server.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", nargs="+", help="checkouts whose studio/robot_view.py to compare")
    parser.add_argument("--clients", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    for _ in range(args.rounds):
        for root in args.roots:
            print(measure(root, args.clients), flush=True)


if __name__ == "__main__":
    main()
