#!/usr/bin/env python3
"""Writes the synthetic trajectory pair behind docs/eval/example_heat_map.png (standard library only).

    python3 docs/eval/example_trajectories.py OUT_DIR
    nirslam eval OUT_DIR/estimate.txt OUT_DIR/groundtruth.csv --plot docs/eval/example_heat_map.png

Ground truth: a camera carried twice around an 8 m x 5 m room at 1.2 m height, 60 s, 200 Hz,
EuRoC ground-truth CSV (timestamp in ns, position, quaternion w x y z). Estimate: 20 Hz TUM,
3 ms late, with a random-walk position drift, a 2 % scale drift over the run, and moved into its
own frame by a Sim(3) (scale 0.37, as a monocular odometry would report).
"""

import math
import os
import random
import sys


def quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def quat_axis(axis, angle):
    s = math.sin(angle / 2)
    return (math.cos(angle / 2), axis[0] * s, axis[1] * s, axis[2] * s)


def rotate(q, v):
    w, x, y, z = quat_mul(quat_mul(q, (0.0, *v)), (q[0], -q[1], -q[2], -q[3]))
    return (x, y, z)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "."
    os.makedirs(out, exist_ok=True)
    t0_ns = 1_700_000_000_000_000_000
    rate, duration = 200, 60.0
    # Camera axes: z forward along the path, y down (world z up).
    cam_from_heading = quat_mul(quat_axis((0, 0, 1), -math.pi / 2), quat_axis((1, 0, 0), -math.pi / 2))
    gt = []
    for k in range(int(rate * duration)):
        t = k / rate
        a = 2 * math.pi * 2 * t / duration
        p = (4.0 * math.cos(a), 2.5 * math.sin(a) + 0.6 * math.sin(3 * a), 1.2 + 0.05 * math.sin(7 * a))
        heading = math.atan2(2.5 * math.cos(a) + 1.8 * math.cos(3 * a), -4.0 * math.sin(a))
        q = quat_mul(quat_axis((0, 0, 1), heading), cam_from_heading)
        gt.append((t0_ns + k * 5_000_000, p, q))
    with open(os.path.join(out, "groundtruth.csv"), "w") as f:
        f.write("#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n")
        for ns, p, q in gt:
            f.write("%d,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f\n" % (ns, *p, *q))

    random.seed(11)
    sim3_q = quat_mul(quat_mul(quat_axis((0, 0, 1), 0.7), quat_axis((1, 0, 0), -0.3)), quat_axis((0, 1, 0), 1.1))
    sim3_t, sim3_s = (12.0, -4.5, 2.25), 0.37
    drift = [0.0, 0.0, 0.0]
    with open(os.path.join(out, "estimate.txt"), "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for k in range(0, len(gt), 10):
            ns, p, q = gt[k]
            drift[0] += random.gauss(0, 0.004) + 0.0006
            drift[1] += random.gauss(0, 0.004) - 0.0002
            drift[2] += random.gauss(0, 0.0012)
            grow = 1.0 + 0.02 * k / len(gt)
            p = tuple(grow * p[i] + drift[i] for i in range(3))
            r = rotate(sim3_q, p)
            p_est = tuple(sim3_s * r[i] + sim3_t[i] for i in range(3))
            w, x, y, z = quat_mul(sim3_q, q)
            f.write("%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n" % ((ns + 3_000_000) * 1e-9, *p_est, x, y, z, w))


if __name__ == "__main__":
    main()
