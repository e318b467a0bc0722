#!/usr/bin/env python3
"""Photometric calibration errors of a `nirslam bench` output's lamp-mode runs against the
simulator's ground truth (README, "Illuminator correction", the lamp mode fully online).

Usage: tests/tools/colit_calibration_errors.py BENCH_DIR [MODE] [--offsets OFFSETS_DIR ...]

--offsets adds the runs of `tests/tools/start_offsets.sh ... OFFSETS_DIR --mode illuminated`
(OFFSETS_DIR/runs/SEQ_from_N/calibration, their truth from BENCH_DIR/sequences/SEQ_*) and prints
the summary over all rows (the 36 runs of README "Illuminator correction", session 37).

For every BENCH_DIR/runs/SEQ/MODE (MODE: illuminated by default) with its sequence in
BENCH_DIR/sequences/SEQ_*: the response as the mean / max difference over all 256 grey levels
of the two inverse responses (pcalib.txt), each scaled to 255 at grey 255 (the irradiance scale
is a normalisation, not data); the halo factor as the mean / max |V_est(x) - V_lens(x) B(x)| over
a grid of every 8th pixel, V_est from calibration.json's vignette coefficients, V_lens the
simulator's lens vignette and B = cos(alpha)^m its lamp's beam about the optical axis (the
lamp's 5 cm offset from the lens is left out: under 1 degree beyond 3 m); where calibration.json
has the beam (lamp_beam_exponent and lamp_beam_lens), the same for the estimate in that form,
V_lens,est cos(alpha)^m_est, which the odometry's lamp factor applies (column "V_lens cos^m"); and
a last line with what the sextic alone costs with the exact model on the camera (halo_floors); the exposures as the
median relative error of the online estimates (calibration.json's `exposures`) against the
reported ones, after the one factor that aligns them best in log (the median ratio), over the
frames the front end estimated from its tracks. The frames it restarted at the reported value
(every back-end update restarts the chain) are counted, not compared: their error is 0 by
construction, and with them restarted every few frames the figure is a short chain's, not the
long chain of the co-lit table's exposure pass (PhotometricAccuracy.CoLitTable). The
response's column "modulo s" is its mean difference in the observed grey range (calibration.json's
`observed`) after the one irradiance scale s that fits it best (as the co-lit table's "observed
range modulo the irradiance scale"): without saturated samples the data fix the curve's shape
there and leave s to the continuation above, so a large response error with a small one modulo
s is the scale's. Python's standard library only.
"""
import glob
import json
import math
import os
import sys


def radial(v, r):
    r2 = r * r
    return 1.0 + r2 * (v[0] + r2 * (v[1] + r2 * v[2]))


def read_inverse_response(path):
    values = [float(t) for t in open(path).read().split()]
    if len(values) != 256:
        sys.exit(f"{path}: expected 256 values, got {len(values)}")
    return [255.0 * x / values[-1] for x in values]


ESTIMATED, RESTARTED = 0, 2  # ExposureStatus in exposure_estimator.hpp


def median(values):
    values = sorted(values)
    return values[len(values) // 2]


def median_of(values):
    """The median as the README's summaries state it (the two middle values averaged for an even
    count); median() above takes the upper one, which the exposure column has always used."""
    values = sorted(values)
    middle = len(values) // 2
    return values[middle] if len(values) % 2 else 0.5 * (values[middle - 1] + values[middle])


def modulo_scale(estimate, truth, grey_range):
    """(mean |s G_est - G_true| over the observed grey levels at the best s, s); both 256-level
    inverse responses scaled to 255 at grey 255. s by a scan in log (the mean absolute error is
    not smooth)."""
    low, high = max(0, int(math.ceil(grey_range[0]))), min(255, int(math.floor(grey_range[1])))
    levels = range(low, high + 1)
    if len(levels) < 2:
        return None, None
    best = None
    for i in range(-700, 701):
        s = math.exp(i / 500.0)
        error = sum(abs(s * estimate[g] - truth[g]) for g in levels) / len(levels)
        if best is None or error < best[0]:
            best = (error, s)
    return best


def exposure_errors(calibration):
    """(median |e_est / (s e_reported) - 1| in per cent over the estimated frames, s the median
    ratio, or None; the number of frames restarted at the reported value)."""
    ratios, restarted = [], 0
    for sample in calibration.get("exposures", []):
        estimated, reported = sample.get("exposure_estimated"), sample.get("exposure_reported")
        restarted += sample.get("status") == RESTARTED
        if sample.get("status") == ESTIMATED and estimated and reported and estimated > 0 and reported > 0:
            ratios.append(estimated / reported)
    if not ratios:
        return None, restarted
    scale = median(ratios)
    return 100.0 * median([abs(r / scale - 1.0) for r in ratios]), restarted


def solve3(a, b):
    """x with a x = b for a 3 x 3 list of rows (Gaussian elimination with partial pivoting)."""
    m = [row[:] + [rhs] for row, rhs in zip(a, b)]
    for c in range(3):
        pivot = max(range(c, 3), key=lambda r: abs(m[r][c]))
        m[c], m[pivot] = m[pivot], m[c]
        for r in range(c + 1, 3):
            f = m[r][c] / m[c][c]
            m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    x = [0.0, 0.0, 0.0]
    for r in (2, 1, 0):
        x[r] = (m[r][3] - sum(m[r][k] * x[k] for k in range(r + 1, 3))) / m[r][r]
    return x


def sextic_fit(samples):
    """v of 1 + v1 r^2 + v2 r^4 + v3 r^6 closest (least squares) to [(r, value)], V(0) = 1."""
    ata = [[0.0] * 3 for _ in range(3)]
    atb = [0.0] * 3
    for r, value in samples:
        t = r * r
        row = (t, t * t, t * t * t)
        for i in range(3):
            atb[i] += row[i] * (value - 1.0)
            for j in range(3):
                ata[i][j] += row[i] * row[j]
    return solve3(ata, atb)


def halo_grid(cam, lens, m_true):
    """[(r, cos(alpha), V_lens(r) cos(alpha)^m_true)] over every 8th pixel of the camera's image:
    where and against what every halo factor here is measured."""
    fx, fy, cx, cy, w, h = cam["fx"], cam["fy"], cam["cx"], cam["cy"], cam["width"], cam["height"]
    half_diagonal = math.hypot(0.5 * (w - 1), 0.5 * (h - 1))
    grid = []
    for y in range(0, h, 8):
        for x in range(0, w, 8):
            r = math.hypot(x - 0.5 * (w - 1), y - 0.5 * (h - 1)) / half_diagonal
            cos_alpha = 1.0 / math.sqrt(1.0 + ((x - cx) / fx) ** 2 + ((y - cy) / fy) ** 2)
            grid.append((r, cos_alpha, radial(lens, r) * cos_alpha ** m_true))
    return grid


def halo_floors(cam, grid, lens):
    """What the halo factor's representation alone costs on this camera, with the exact model:
    the sextic 1 + v1 r^2 + v2 r^4 + v3 r^6 cannot follow V_lens cos(alpha)^m all the way to the
    corner. Returns (free, flat, given, flat_exact), each but the first (error, m): the sextic
    closest to the truth over the image; the sextic the back end holds for cos(alpha)^m (a flat
    lens, `calibration.lamp_halo: beam`) and for V_lens cos(alpha)^m (the lens given), each fitted
    along the diagonal as BeamHalo does (core/photometric/beam_halo.cpp), at the m that does best;
    and cos(alpha)^m itself (the flat lens in the beam's own form, `beam_halo_exact`) at its best m."""
    fx, fy, cx, cy, w, h = cam["fx"], cam["fy"], cam["cx"], cam["cy"], cam["width"], cam["height"]
    error = lambda v: sum(abs(radial(v, r) - truth) for r, _, truth in grid) / len(grid)
    free = error(sextic_fit([(r, truth) for r, _, truth in grid]))
    diagonal = []
    for i in range(64):
        r = (i + 0.5) / 64
        px, py = 0.5 * (w - 1) * (1 + r), 0.5 * (h - 1) * (1 + r)
        diagonal.append((r, 1.0 / math.sqrt(1.0 + ((px - cx) / fx) ** 2 + ((py - cy) / fy) ** 2)))
    def best(at):
        m = min((0.1 * k for k in range(20, 101)), key=at)
        m = min((m + 0.005 * k for k in range(-20, 21)), key=at)
        return at(m), m
    through_sextic = lambda lens_factor: lambda m: error(sextic_fit([(r, lens_factor(r) * c ** m) for r, c in diagonal]))
    flat_exact = lambda m: sum(abs(c ** m - truth) for _, c, truth in grid) / len(grid)
    return (free, best(through_sextic(lambda r: 1.0)), best(through_sextic(lambda r: radial(lens, r))),
            best(flat_exact))


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    args = sys.argv[1:]
    offsets = []
    while "--offsets" in args:
        at = args.index("--offsets")
        if at + 1 >= len(args):
            sys.exit("--offsets needs a folder")
        offsets.append(args[at + 1])
        del args[at:at + 2]
    bench, mode = args[0], (args[1] if len(args) > 1 else "illuminated")
    rows = []
    floors = None
    runs = [(run, os.path.basename(os.path.dirname(run)), os.path.basename(os.path.dirname(run)))
            for run in sorted(glob.glob(os.path.join(bench, "runs", "*", mode)))]
    for folder in offsets:
        found = sorted(glob.glob(os.path.join(folder, "runs", "*_from_*")))
        if not found:
            sys.exit(f"{folder}: no runs/SEQ_from_N")
        runs += [(run, os.path.basename(run), os.path.basename(run).rsplit("_from_", 1)[0]) for run in found]
    for run, sequence, base in runs:
        folders = glob.glob(os.path.join(bench, "sequences", base + "_*"))
        if not folders:
            sys.exit(f"{run}: no sequence {base}_* in {bench}/sequences")
        truth = json.load(open(os.path.join(folders[0], "groundtruth.json")))
        cam = truth["camera"]
        lens = truth["vignette"]["coefficients"]
        m_true = truth["illuminator"]["beam"]["exponent_m"]
        grid = halo_grid(cam, lens, m_true)
        if floors is None:
            floors = (cam, m_true, halo_floors(cam, grid, lens))
        estimate = json.load(open(os.path.join(run, "calibration", "calibration.json")))
        v = estimate["vignette"]["coefficients"]
        # The beam's own form, V_lens cos(alpha)^m, as the odometry's lamp factor applies it
        # (calibration.json's lamp_beam_lens, from 2026-12-06 on), beside the sextic "vignette".
        m_est, beam_lens = estimate.get("lamp_beam_exponent"), estimate.get("lamp_beam_lens")
        halo = [abs(radial(v, r) - truth_here) for r, _, truth_here in grid]
        beam_halo = ([abs(radial(beam_lens, r) * c ** m_est - truth_here) for r, c, truth_here in grid]
                     if m_est is not None and beam_lens is not None else [])
        est = read_inverse_response(os.path.join(run, "calibration", "pcalib.txt"))
        tru = read_inverse_response(os.path.join(folders[0], "pcalib.txt"))
        response = [abs(a - b) for a, b in zip(est, tru)]
        grey_range = (estimate.get("observed") or {}).get("grey_range")
        shape, scale = modulo_scale(est, tru, grey_range) if grey_range else (None, None)
        exposure, restarted = exposure_errors(estimate)
        # Where the exposure hardly varies the back end holds the response at its start (the
        # gamma preset, which is the simulator's curve too): an error of 0 there says nothing.
        held = "response held" in (estimate.get("convergence") or {}).get("status", "")
        rows.append((sequence, sum(response) / 256, max(response), sum(halo) / len(halo), max(halo),
                     estimate.get("lamp_beam_exponent"), exposure, restarted, shape, scale, held,
                     sum(beam_halo) / len(beam_halo) if beam_halo else None))
    if not rows:
        sys.exit(f"no runs in {bench}/runs/*/{mode}")
    print("| Sequence | response mean / max [grey levels] | modulo s (s) | halo factor mean / max | V_lens cos^m mean "
          "| beam exponent m | exposure median [%] (frames restarted) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for s, rm, rx, hm, hx, m, e, restarted, shape, scale, held, bh in rows:
        modulo = "-" if shape is None or held else f"{shape:.2f} ({scale:.2f})"
        response = "held at its start" if held else f"{rm:.2f} / {rx:.1f}"
        print(f"| {s} | {response} | {modulo} | {hm:.4f} / {hx:.3f} | {'-' if bh is None else f'{bh:.4f}'} "
              f"| {'-' if m is None else f'{m:.2f}'} | {'-' if e is None else f'{e:.2f}'} ({restarted}) |")
    n = len(rows)
    estimated = [r for r in rows if not r[10]]  # the response's columns: runs that estimated it
    exposures = [r[6] for r in rows if r[6] is not None]
    exposure_mean = f"{sum(exposures) / len(exposures):.2f}" if exposures else "-"
    shapes = [r[8] for r in estimated if r[8] is not None]
    shape_mean = f"{sum(shapes) / len(shapes):.2f}" if shapes else "-"
    response_mean = f"{sum(r[1] for r in estimated) / len(estimated):.2f}" if estimated else "-"
    beams = [r[11] for r in rows if r[11] is not None]
    beam_mean = f"{sum(beams) / len(beams):.4f}" if beams else "-"
    print(f"| mean | {response_mean} | {shape_mean} | {sum(r[3] for r in rows) / n:.4f} | {beam_mean} | | {exposure_mean} |")
    held_note = f" ({n - len(estimated)} held the response at its start, left out of its columns)" if len(estimated) < n else ""
    beam_note = f" (as V_lens cos^m: {sum(b < 0.005 for b in beams)} of {len(beams)})" if beams else ""
    print(f"\nresponse mean < 2 on {sum(r[1] < 2 for r in estimated)} of {len(estimated)}{held_note}, halo mean < 0.005 on "
          f"{sum(r[3] < 0.005 for r in rows)} of {n}{beam_note}")
    cam, m_true, (free, flat, given, flat_exact) = floors
    print(f"the halo factor's sextic alone, with the exact model (first run's camera, fx {cam['fx']:.1f}, true m "
          f"{m_true:.3f}): closest to V_lens B over the image {free:.4f}; through cos(alpha)^m along the diagonal "
          f"(a flat lens, lamp_halo: beam) {flat[0]:.4f} at m {flat[1]:.2f}; through V_lens cos(alpha)^m {given[0]:.4f} "
          f"at m {given[1]:.2f}; a flat lens in the beam's own form, cos(alpha)^m, {flat_exact[0]:.4f} at m "
          f"{flat_exact[1]:.2f}")
    if offsets:
        response_median = f"{median_of([r[1] for r in estimated]):.2f}" if estimated else "-"
        print(f"over the {n} runs: response median {response_median}, above 8 grey levels on "
              f"{sum(r[1] > 8 for r in estimated)}; halo factor median {median_of([r[3] for r in rows]):.4f}"
              + (f" (as V_lens cos^m {median_of(beams):.4f})" if beams else ""))


if __name__ == "__main__":
    main()
