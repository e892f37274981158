"""graybox_native's latency as a Python controller sees it: predict and linearize of one
state, timed call by call after a warm-up (median, 99th percentile, mean in microseconds), then
predict's throughput from 1 and from 8 threads sharing the model, as JSON lines.
`graybox-lab bench infer --model F --python PY` runs it beside the Rust, C and gRPC figures.

Usage: python native_latency.py MODEL.gbx CALLS < STATE, where STATE holds x (2n) then u (m).
"""
import json
import os
import sys
import threading
import time

# NumPy's OpenBLAS keeps a pool of threads, one a core, that spin for a while after starting:
# on two cores they took the time the eight callers' threads were measured on (1.5× instead
# of 1.7× from eight threads). No BLAS call is made here; a controller process does the same.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import graybox_native  # noqa: E402


def report(bench, us, **extra):
    us = np.sort(np.asarray(us))
    pct = lambda p: float(us[int(round((len(us) - 1) * p))])
    print(json.dumps({"bench": bench, "calls": len(us), "p50_us": pct(0.5),
                      "p99_us": pct(0.99), "mean_us": float(us.mean()), **extra}), flush=True)


def timed(calls, f):
    for _ in range(calls // 10):
        f()
    out = np.empty(calls)
    clock = time.perf_counter_ns
    for i in range(calls):
        t = clock()
        f()
        out[i] = (clock() - t) * 1e-3
    return out


def throughput(model, x, u, threads, calls):
    """Predict calls per second, `threads` threads each making `calls` of them at once."""
    start = threading.Barrier(threads + 1)

    def work():
        start.wait()
        for _ in range(calls):
            model.predict(x, u)

    pool = [threading.Thread(target=work) for _ in range(threads)]
    for t in pool:
        t.start()
    start.wait()
    t0 = time.perf_counter()
    for t in pool:
        t.join()
    return threads * calls / (time.perf_counter() - t0)


def main():
    path, calls = sys.argv[1], int(sys.argv[2])
    model = graybox_native.load(path)
    nx, m = 2 * model.info["n"], model.info["m"]
    state = np.array(sys.stdin.read().split(), dtype=np.float64)
    x, u = state[:nx].copy(), state[nx:nx + m].copy()
    note = {"transport": "graybox_native, in the Python process"}
    report("python_predict_1", timed(calls, lambda: model.predict(x, u)), **note)
    report("python_linearize_1", timed(calls, lambda: model.linearize(x, u)), **note)
    # Three interleaved rounds of one thread, then eight, each making `calls` calls: the
    # median round's ratio (a round lasts well under a second, so one round is noisy).
    throughput(model, x, u, 1, calls // 10)  # warm-up
    rounds = sorted(((throughput(model, x, u, 8, calls) / (one := throughput(model, x, u, 1, calls))), one)
                    for _ in range(3))
    speedup, one = rounds[1]
    print(json.dumps({"bench": "python_predict_1_threads", "threads": 8, "rounds": 3,
                      "calls_per_thread": calls, "calls_per_second_1_thread": one,
                      "calls_per_second_8_threads": speedup * one, "speedup": speedup,
                      "speedups": [r[0] for r in rounds], **note}), flush=True)


if __name__ == "__main__":
    main()
