#!/usr/bin/env python3
"""Tracks a TUM RGB-D folder frame by frame with sdoslam's Python module and plots the
trajectory from above (with the ground truth, aligned, where the folder has it).

From the repository root, after scripts/build.sh:

    PYTHONPATH=build/python python3 examples/track_tum.py \\
        ../shared/data/tum_fr2_desk_50 configs/tum_fr2.yaml --out trajectory.png
"""

import argparse
import sys
import time

import numpy as np

try:
    import sdoslam
except ImportError:
    sys.exit("sdoslam: module not found; build it (scripts/build.sh) and run with "
             "PYTHONPATH=build/python")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", help="sequence folder (rgb.txt, depth.txt, rgb/, depth/)")
    parser.add_argument("config", help="run config, e.g. configs/tum_fr2.yaml")
    parser.add_argument("--mode", default="sdo", choices=["sdo", "conventional"])
    parser.add_argument("--sequential", action="store_true",
                        help="map inline (deterministic) instead of in a thread of its own")
    parser.add_argument("--out", default="trajectory.png", help="the plot (PNG)")
    args = parser.parse_args()

    # matplotlib is the example's own dependency, not the module's.
    try:
        import matplotlib
        matplotlib.use("Agg")  # a file, no window: works without a display
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("matplotlib is missing: apt-get install python3-matplotlib")

    dataset = sdoslam.Dataset(args.dataset, args.config)
    start = time.perf_counter()
    with sdoslam.Pipeline(args.config, mode=args.mode, sequential=args.sequential) as pipeline:
        for bgr, depth_m, timestamp in dataset:
            result = pipeline.track(bgr, depth_m, timestamp)
            if result["index"] % 100 == 0:
                print(f"frame {result['index']}: {result['state']}, "
                      f"{result['keyframes']} keyframes")
    # After the with block mapping has finished: the trajectory is final.
    trajectory = pipeline.trajectory()
    seconds = time.perf_counter() - start
    print(f"{pipeline.frames} frames, {len(trajectory)} tracked, "
          f"{pipeline.frames / seconds:.1f} fps")

    figure, axes = plt.subplots(figsize=(6, 6))
    if dataset.ground_truth is not None and len(trajectory) >= 3:
        evaluation = sdoslam.evaluate(dataset.ground_truth, trajectory)
        print(f"ATE rmse {evaluation['ate']['rmse']:.4f} m")
        matched = evaluation["matched"]
        gt, est = matched["ground_truth"], matched["estimate_aligned"]
        # The plane of the two axes along which the ground truth extends most.
        u, v = sorted(np.argsort(np.ptp(gt, axis=0))[-2:])
        axes.plot(gt[:, u], gt[:, v], "k-", label="ground truth")
        axes.plot(est[:, u], est[:, v], "-", label=f"sdoslam {args.mode} (aligned)")
        axes.set_title(f"ATE rmse {1000 * evaluation['ate']['rmse']:.1f} mm")
    else:
        # The world frame is the first camera's (x right, y down, z forward): seen from above.
        u, v = 0, 2
        axes.plot(trajectory[:, 1 + u], trajectory[:, 1 + v], "-", label=f"sdoslam {args.mode}")
    axes.set_xlabel(f"{'xyz'[u]} [m]")
    axes.set_ylabel(f"{'xyz'[v]} [m]")
    axes.set_aspect("equal", adjustable="datalim")
    axes.legend()
    figure.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
