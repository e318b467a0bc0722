#!/usr/bin/env python3
"""The online exposure estimates of a `nirslam run` (calibration/calibration.json's `exposures`,
what the GUI plots and times.txt holds) against a sequence's true exposures (its times.txt).

Usage: tests/tools/online_exposure_errors.py RUN_DIR SEQUENCE_DIR [FIRST_FRAME]

Prints, over the frames from FIRST_FRAME (10 by default: after the auto exposure's first ramp)
that have an estimate (estimated from tracks, first frame, or restarted; frames that kept the
last estimate are counted apart): the median and 90th percentile of |log(e_est / e_true)| after
the one factor that aligns them best (the median: the exposures' scale is a normalisation), and
after a fitted power as well (log e_est = a + gamma log e_true, least squares: without reported
exposures the response's gamma is not determined, so the estimates may be e_true^gamma). Run on
a sequence without exposures in its times.txt (two columns), the chain never restarts at a
reported value. Python's standard library only.
"""
import collections
import json
import math
import os
import sys

STATUS = {0: "estimated", 1: "first frame", 2: "restarted"}  # ExposureStatus, exposure_estimator.hpp


def read_true_exposures(sequence):
    path = os.path.join(sequence, "times.txt")
    exposures = {}
    for number, line in enumerate(open(path), 1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        if len(fields) < 3:
            sys.exit(f"{path}:{number}: expected 'id time exposure', got {line.strip()!r}")
        exposures[int(fields[0])] = float(fields[2])
    return exposures


def quantile(values, q):
    values = sorted(values)
    return values[int(q * (len(values) - 1))]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    run, sequence = sys.argv[1], sys.argv[2]
    first = int(sys.argv[3]) if len(sys.argv) > 3 else 10
    truth = read_true_exposures(sequence)
    calibration_path = os.path.join(run, "calibration", "calibration.json")
    samples = json.load(open(calibration_path)).get("exposures")
    if not samples:
        sys.exit(f"{calibration_path}: no 'exposures'")
    statuses = collections.Counter()
    pairs = []
    for s in samples:
        index, estimated = s.get("index"), s.get("exposure_estimated")
        if index is None or index < first or index not in truth:
            continue
        status = STATUS.get(s.get("status"), "kept")
        statuses[status] += 1
        if status != "kept" and estimated and estimated > 0 and truth[index] > 0:
            pairs.append((math.log(truth[index]), math.log(estimated)))
    if len(pairs) < 3:
        sys.exit(f"{calibration_path}: fewer than 3 estimated frames from frame {first}")
    offsets = [y - x for x, y in pairs]
    scale = quantile(offsets, 0.5)
    scale_errors = [abs(o - scale) for o in offsets]
    n = len(pairs)
    mean_x, mean_y = sum(x for x, _ in pairs) / n, sum(y for _, y in pairs) / n
    spread = sum((x - mean_x) ** 2 for x, _ in pairs)
    gamma = sum((x - mean_x) * (y - mean_y) for x, y in pairs) / spread if spread > 0 else 1.0
    power_errors = [abs(y - mean_y - gamma * (x - mean_x)) for x, y in pairs]
    print(f"{run}: frames from {first}: " + ", ".join(f"{k} {v}" for k, v in sorted(statuses.items())))
    print(f"  one factor:       |log error| median {100 * quantile(scale_errors, 0.5):.2f} %, "
          f"90 % {100 * quantile(scale_errors, 0.9):.2f} %, max {100 * max(scale_errors):.2f} %")
    print(f"  factor and power: gamma {gamma:.3f}, |log error| median {100 * quantile(power_errors, 0.5):.2f} %, "
          f"90 % {100 * quantile(power_errors, 0.9):.2f} %, max {100 * max(power_errors):.2f} %")


if __name__ == "__main__":
    main()
