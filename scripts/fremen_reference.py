#!/usr/bin/env python3
"""Plain FreMEn (Krajník et al.), written from the published formula with numpy, as the
reference the greg_door benchmark (`froctomap-bench greg-door`) compares froctomap with.

A binary state s(t) is modelled by its mean over the training samples plus the k strongest
of the periods 7 days / j (j = 1..24), each from the training spectrum on the whole span:

    gamma_P = (1/n) * sum_i (s_i - mean) * exp(-2*pi*1j * t_i / P)
    p(t)    = clip(mean + sum_{k strongest |gamma_P|} 2*|gamma_P| * cos(2*pi*t/P + arg gamma_P), 0, 1)

Input: the greg_door files (`training_data.txt`: `unix_time state` per line;
`test_times_W.txt` / `test_data_W.txt` per test week W). The modelled state is the door
panel's occupancy, `1 - state` (the panel is occupied while the door is closed, state 0).
Output (stdout, JSON): per order k and test week, the thresholded error (p > 0.5), the
Brier score and the log loss (p clipped to [eps, 1 - eps]) on every `stride`-th test sample,
and the same for the static mean.

With `--validate-until T` the test files are not read: the model is fitted on the training
samples before T only, and the weeks are the held-back training weeks, week W being the
training samples in [start + (W-1)·7 days, start + W·7 days) (start = the first training
sample).

Usage: fremen_reference.py DATA_DIR --weeks 1,2,...,9 --stride 10 --orders 0,1,2,3,4,5
       [--train-from UNIX_TIME] [--validate-until UNIX_TIME] [--eps 1e-3]
"""
import argparse
import json

import numpy as np

WEEK = 7 * 86_400.0
HARMONICS = 24


def load_pairs(path):
    data = np.loadtxt(path, dtype=np.float64)
    return data[:, 0], data[:, 1]


def scores(p, s, eps):
    clipped = np.clip(p, eps, 1.0 - eps)
    return {
        "error_percent": float(100.0 * np.mean((p > 0.5) != (s > 0.5))),
        "brier": float(np.mean((p - s) ** 2)),
        "log_loss": float(np.mean(-(s * np.log(clipped) + (1 - s) * np.log(1 - clipped)))),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("data")
    parser.add_argument("--weeks", default="1,2,3,4,5,6,7,8,9")
    parser.add_argument("--stride", type=int, default=10)
    parser.add_argument("--orders", default="0,1,2,3,4,5")
    parser.add_argument("--train-from", type=float, default=None)
    parser.add_argument("--validate-until", type=float, default=None)
    parser.add_argument("--eps", type=float, default=1e-3)
    args = parser.parse_args()

    t, state = load_pairs(f"{args.data}/training_data.txt")
    all_t, all_state, start = t, state, float(t[0])
    if args.validate_until is not None:
        keep = t < args.validate_until
        t, state = t[keep], state[keep]
    if args.train_from is not None:
        keep = t >= args.train_from
        t, state = t[keep], state[keep]
    s = 1.0 - state  # occupied while closed
    mean = float(s.mean())
    periods = WEEK / np.arange(1, HARMONICS + 1)
    gamma = np.array([np.mean((s - mean) * np.exp(-2j * np.pi * t / p)) for p in periods])
    strongest = np.argsort(-np.abs(gamma), kind="stable")

    out = {"mean": mean, "samples": int(len(t)), "periods_seconds": periods.tolist(),
           "strongest_first": [float(periods[j]) for j in strongest], "weeks": {}}
    orders = [int(k) for k in args.orders.split(",")]
    for week in [int(w) for w in args.weeks.split(",")]:
        if args.validate_until is None:
            times = np.loadtxt(f"{args.data}/test_times_{week}.txt", dtype=np.float64)
            truth = 1.0 - np.loadtxt(f"{args.data}/test_data_{week}.txt", dtype=np.float64)
        else:
            lo, hi = start + (week - 1) * WEEK, start + week * WEEK
            inside = (all_t >= max(lo, args.validate_until)) & (all_t < hi)
            times, truth = all_t[inside], 1.0 - all_state[inside]
            if len(times) == 0:
                raise SystemExit(f"validation week {week}: no training samples after the fit")
        times, truth = times[:: args.stride], truth[:: args.stride]
        row = {"static mean": scores(np.full_like(times, mean), truth, args.eps)}
        for k in orders:
            p = np.full_like(times, mean)
            for j in strongest[:k]:
                g = gamma[j]
                p += 2.0 * np.abs(g) * np.cos(2.0 * np.pi * times / periods[j] + np.angle(g))
            row[f"fremen k={k}"] = scores(np.clip(p, 0.0, 1.0), truth, args.eps)
        out["weeks"][str(week)] = row
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
