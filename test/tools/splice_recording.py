#!/usr/bin/env python3
"""A recording made of stretches of others, each restamped to follow the previous one frame period
later: a kidnapped robot (the camera jumps between two places), or a run that starts elsewhere.

    splice_recording.py OUT SRC:START:END [SRC:START:END ...]

OUT gets frames [START, END) of each SRC's associations.txt in turn (END empty: to the last), the
first SRC's calibration.yaml, the ground truth of those frames on their new stamps and links to
the images. A single stretch (a run that starts elsewhere) keeps its wheel log's frames over its
span, restamped; several leave it out (a kidnap the wheels would not see), as they do the fisheye
stream. Prints the ground-truth distance of each jump between stretches, metres.
"""
import math
import os
import shutil
import sys


def read_rows(path):
    with open(path) as f:
        return [line.split() for line in f if line.strip() and not line.startswith("#")]


def splice_can_log(src, out, begin_s, end_s, shift):
    """The candump -l lines of SRC's can.log stamped within [begin_s, end_s], restamped by shift."""
    path = os.path.join(src, "can.log")
    if not os.path.exists(path):
        return
    with open(path) as f, open(os.path.join(out, "can.log"), "w") as log:
        for line in f:
            if not line.startswith("("):
                continue
            stamp_text, rest = line[1:].split(")", 1)
            stamp = float(stamp_text)
            if begin_s <= stamp <= end_s:
                log.write(f"({stamp + shift:.6f}){rest}")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = sys.argv[1]
    stretches = []
    for spec in sys.argv[2:]:
        parts = spec.rsplit(":", 2)
        if len(parts) != 3:
            sys.exit(f"splice_recording: '{spec}' is not SRC:START:END")
        src = os.path.abspath(parts[0])
        pairs = read_rows(os.path.join(src, "associations.txt"))
        start = int(parts[1] or 0)
        end = int(parts[2]) if parts[2] else len(pairs)
        if not 0 <= start < end <= len(pairs):
            sys.exit(f"splice_recording: [{start}, {end}) does not fit the {len(pairs)} frames of {src}")
        ground_truth = [(float(row[0]), row[1:]) for row in read_rows(os.path.join(src, "groundtruth.txt"))]
        stretches.append((src, pairs, start, end, ground_truth))

    os.makedirs(os.path.join(out, "rgb"))
    os.makedirs(os.path.join(out, "depth"))
    if os.path.exists(os.path.join(stretches[0][0], "calibration.yaml")):
        shutil.copy(os.path.join(stretches[0][0], "calibration.yaml"), out)
    next_stamp = None
    last_position = None
    with open(os.path.join(out, "associations.txt"), "w") as assoc, \
            open(os.path.join(out, "groundtruth.txt"), "w") as gt:
        gt.write("# ground truth of " + " ".join(sys.argv[2:]) + "\n# timestamp tx ty tz qx qy qz qw\n")
        for number, (src, pairs, start, end, ground_truth) in enumerate(stretches):
            period = (float(pairs[-1][0]) - float(pairs[0][0])) / max(1, len(pairs) - 1)
            shift = 0.0 if next_stamp is None else next_stamp - float(pairs[start][0])
            # The ground truth over the stretch's span (its own rate: TUM's is 100 Hz).
            begin_s, end_s = float(pairs[start][0]) - 0.005, float(pairs[end - 1][0]) + 0.005
            span = [(stamp, pose) for stamp, pose in ground_truth if begin_s <= stamp <= end_s]
            if last_position is not None and span:
                print(f"{math.dist(last_position, [float(v) for v in span[0][1][:3]]):.3f}")
            for stamp, pose in span:
                gt.write(f"{stamp + shift:.6f} " + " ".join(pose) + "\n")
            if span:
                last_position = [float(v) for v in span[-1][1][:3]]
            for row in pairs[start:end]:
                rgb_stamp = f"{float(row[0]) + shift:.6f}"
                depth_stamp = f"{float(row[2]) + shift:.6f}"
                # Links named per stretch: two sources may share file names.
                rgb = f"rgb/{number}_{os.path.basename(row[1])}"
                depth = f"depth/{number}_{os.path.basename(row[3])}"
                os.symlink(os.path.join(src, row[1]), os.path.join(out, rgb))
                os.symlink(os.path.join(src, row[3]), os.path.join(out, depth))
                assoc.write(f"{rgb_stamp} {rgb} {depth_stamp} {depth}\n")
            if len(stretches) == 1:
                splice_can_log(src, out, begin_s - 0.05, end_s, shift)  # a wheel frame before the first image
            next_stamp = float(pairs[end - 1][0]) + shift + period


if __name__ == "__main__":
    main()
