"""Kestrel releases the GIL while it computes: another Python thread runs meanwhile."""

import threading
import time

import numpy as np

import kestrel


def _frames(width=640, height=480):
    rng = np.random.default_rng(7)
    noise = rng.random((height // 8 + 1, width // 8 + 1))
    # Blocky texture, upsampled: corners everywhere for LK.
    scene = np.kron(noise, np.ones((8, 8)))[:height, :width]
    first = (40 + 180 * scene).astype(np.uint8)
    second = np.roll(first, 1, axis=1)
    return first, second


def _python_steps_during(call):
    """How many Python loop steps the main thread makes while `call` runs in another thread,
    and how long the call took, seconds."""
    inside = threading.Event()
    done = threading.Event()
    took = []

    def worker():
        inside.set()
        start = time.perf_counter()
        call()
        took.append(time.perf_counter() - start)
        done.set()

    thread = threading.Thread(target=worker)
    thread.start()
    inside.wait()
    steps = 0
    while not done.is_set():
        steps += 1
    thread.join()
    return steps, took[0]


def _share_of_time_the_main_thread_ran(call):
    """The main thread's loop steps during `call`, against its steps during a sleep (which
    releases the GIL) of the same length: about 1 when `call` releases the GIL, near 0 when it
    holds it (a regular expression that backtracks for 0.7 s in C gave 0.01)."""
    steps, took = _python_steps_during(call)
    idle_steps, idle = _python_steps_during(lambda: time.sleep(0.2))
    return (steps / took) / (idle_steps / idle)


def test_lk_lets_other_threads_run():
    first, second = _frames()
    ys, xs = np.mgrid[16:464:8, 16:624:8]
    points = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.float32).reshape(-1, 1, 2)

    def call():
        for _ in range(5):
            kestrel.calc_optical_flow_pyr_lk(first, second, points, None, win_size=(21, 21))

    # Measured: 0.85-1.04 over three runs each on an idle 2-core machine, 0.43-0.46 while two
    # builds ran beside it (the main thread then shares its core); a call that holds the GIL:
    # 0.008.
    assert _share_of_time_the_main_thread_ran(call) > 0.2


def test_dense_flow_lets_other_threads_run():
    first, second = _frames()

    def call():
        for _ in range(5):
            kestrel.dense_flow(first, second, cell=4)

    # As for LK: about 1 on an idle machine, about half under load; 0.008 holding the GIL.
    assert _share_of_time_the_main_thread_ran(call) > 0.2
