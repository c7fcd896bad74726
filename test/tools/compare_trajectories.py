#!/usr/bin/env python3
"""Largest per-pose difference between the trajectories of two same_results.sh outputs.

    compare_trajectories.py BEFORE AFTER [--tolerance-m 1e-6] [--tolerance-deg 1e-4]

Exits 1 when a run is missing, a pose count differs or a pose differs beyond the tolerances.
"""
import argparse
import json
import math
import pathlib
import sys


def poses(path):
    rows = []
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith('#'):
            rows.append([float(v) for v in line.split()])
    return rows


def angle_deg(q1, q2):
    dot = abs(sum(a * b for a, b in zip(q1, q2)))
    n1 = math.sqrt(sum(a * a for a in q1))
    n2 = math.sqrt(sum(a * a for a in q2))
    return math.degrees(2.0 * math.acos(min(1.0, dot / (n1 * n2))))


def ate(run):
    report = run / 'report.json'
    if not report.exists():
        return None
    try:
        return json.loads(report.read_text()).get('ate_rmse_m')
    except ValueError:
        return None


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument('before', type=pathlib.Path)
    parser.add_argument('after', type=pathlib.Path)
    parser.add_argument('--tolerance-m', type=float, default=1e-6)
    parser.add_argument('--tolerance-deg', type=float, default=1e-4)
    args = parser.parse_args()
    ok = True
    print(f"{'run':32} {'poses':>6} {'max dt [m]':>11} {'max dR [deg]':>12} {'ATE before':>11} {'ATE after':>11}")
    for before in sorted(p for p in args.before.iterdir() if (p / 'trajectory.txt').exists()):
        after = args.after / before.name
        if not (after / 'trajectory.txt').exists():
            print(f'{before.name:32} missing in {args.after}')
            ok = False
            continue
        a, b = poses(before / 'trajectory.txt'), poses(after / 'trajectory.txt')
        if len(a) != len(b):
            print(f'{before.name:32} {len(a)} against {len(b)} poses')
            ok = False
            continue
        dt = max((math.dist(p[1:4], q[1:4]) for p, q in zip(a, b)), default=0.0)
        dr = max((angle_deg(p[4:8], q[4:8]) for p, q in zip(a, b)), default=0.0)
        same = dt <= args.tolerance_m and dr <= args.tolerance_deg
        ok = ok and same
        ate_a, ate_b = ate(before), ate(after)
        fmt = lambda v: f'{v:11.6f}' if isinstance(v, float) else f'{"-":>11}'
        print(f'{before.name:32} {len(a):6} {dt:11.2e} {dr:12.2e} {fmt(ate_a)} {fmt(ate_b)}' + ('' if same else '  DIFFERENT'))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
