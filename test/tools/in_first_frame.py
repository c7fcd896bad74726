#!/usr/bin/env python3
"""A second run's position error in a first run's frame: the first run's ATE alignment (a rigid
transform, estimate to ground truth, Horn's closed form) applied to the second run's trajectory,
against the second run's own ground truth (both ground truths in the scene's frame, as the
simulator writes them). For a run started with --load-map in the first run's saved map.

    in_first_frame.py FIRST_GT FIRST_TRAJECTORY SECOND_GT SECOND_TRAJECTORY

TUM trajectories; poses associated to ground truth within 20 ms. Prints the first run's ATE RMSE
and the second run's RMSE and largest error, metres.
"""
import bisect
import math
import sys


def read(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.strip() and not line.startswith('#'):
                v = [float(x) for x in line.split()]
                rows.append((v[0], v[1:4]))
    rows.sort()
    return rows


def associate(truth, estimate, max_dt=0.02):
    stamps = [s for s, _ in truth]
    pairs = []
    for stamp, position in estimate:
        i = bisect.bisect_left(stamps, stamp)
        near = min((j for j in (i - 1, i) if 0 <= j < len(stamps)), key=lambda j: abs(stamps[j] - stamp), default=None)
        if near is not None and abs(stamps[near] - stamp) <= max_dt:
            pairs.append((truth[near][1], position))
    return pairs


def largest_eigenvector(a):
    """Of a symmetric 4 × 4 matrix, by Jacobi rotations."""
    n = 4
    a = [row[:] for row in a]
    v = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    for _ in range(100):
        if sum(a[i][j] ** 2 for i in range(n) for j in range(n) if i != j) < 1e-22:
            break
        for p in range(n):
            for q in range(p + 1, n):
                if a[p][q] == 0.0:
                    continue
                theta = (a[q][q] - a[p][p]) / (2 * a[p][q])
                t = (1 if theta >= 0 else -1) / (abs(theta) + math.sqrt(theta * theta + 1))
                c = 1 / math.sqrt(t * t + 1)
                s = t * c
                for k in range(n):
                    a[k][p], a[k][q] = c * a[k][p] - s * a[k][q], s * a[k][p] + c * a[k][q]
                for k in range(n):
                    a[p][k], a[q][k] = c * a[p][k] - s * a[q][k], s * a[p][k] + c * a[q][k]
                for k in range(n):
                    v[k][p], v[k][q] = c * v[k][p] - s * v[k][q], s * v[k][p] + c * v[k][q]
    best = max(range(n), key=lambda k: a[k][k])
    return [v[k][best] for k in range(n)]


def align(pairs):
    """R, t with truth ≈ R · estimate + t (Horn 1987)."""
    n = len(pairs)
    mean_t = [sum(g[k] for g, _ in pairs) / n for k in range(3)]
    mean_e = [sum(e[k] for _, e in pairs) / n for k in range(3)]
    s = [[sum((e[a] - mean_e[a]) * (g[b] - mean_t[b]) for g, e in pairs) for b in range(3)] for a in range(3)]
    (xx, xy, xz), (yx, yy, yz), (zx, zy, zz) = s
    w, x, y, z = largest_eigenvector([[xx + yy + zz, yz - zy, zx - xz, xy - yx],
                                      [yz - zy, xx - yy - zz, xy + yx, zx + xz],
                                      [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
                                      [xy - yx, zx + xz, yz + zy, -xx - yy + zz]])
    r = [[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]]
    t = [mean_t[a] - sum(r[a][b] * mean_e[b] for b in range(3)) for a in range(3)]
    return r, t


def errors(pairs, r, t):
    return [math.dist(g, [sum(r[a][b] * e[b] for b in range(3)) + t[a] for a in range(3)]) for g, e in pairs]


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    first = associate(read(sys.argv[1]), read(sys.argv[2]))
    second = associate(read(sys.argv[3]), read(sys.argv[4]))
    if len(first) < 3 or not second:
        sys.exit("too few poses associated with their ground truth")
    r, t = align(first)
    e1, e2 = errors(first, r, t), errors(second, r, t)
    rms = lambda e: math.sqrt(sum(x * x for x in e) / len(e))
    print(f"first run ATE {rms(e1):.5f} m ({len(e1)} poses); second run in its frame: RMSE {rms(e2):.5f} m, "
          f"max {max(e2):.4f} m ({len(e2)} poses)")


if __name__ == '__main__':
    main()
