#!/usr/bin/env python3
"""Maps a synthetic drive with carat from Python and plots the trajectories before and after.

A spinning LiDAR drives twice around a block of the synthetic city; a drifting dead reckoning,
refined by GICP odometry, is the initial guess. The script builds the dense graph, runs the pose-graph baseline and global
registration with exact coresets (M = 29) and with lossless rows, prints the ATE of each as JSON
and draws the trajectories (top view) into a PNG. It exits 1 when global registration does not
beat the initial guess, so that a test can run it.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/map_synthetic_drive.py --out drive.png
"""

import argparse
import json
import sys
import time

import matplotlib
import numpy as np

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt  # noqa: E402

import carat  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="carat-drive.png", help="PNG to write")
    parser.add_argument("--frames", type=int, default=60, help="frames over both laps")
    parser.add_argument("--threads", type=int, default=2, help="threads for every stage")
    args = parser.parse_args()

    start = time.monotonic()
    drive = carat.simulate(frames=args.frames, laps=2, threads=args.threads)
    simulate_s = time.monotonic() - start
    runs = {
        "drifting dead reckoning": drive.drift,
        "initial guess (GICP odometry)": drive.initial,
        "pose graph (GICP Hessian)": carat.pose_graph(drive.frames, drive.graph, drive.initial, threads=args.threads).poses,
        "global registration, exact M = 29": carat.optimize(drive.frames, drive.graph, drive.initial, sampling="exact", threads=args.threads).poses,
        "global registration, lossless": carat.optimize(drive.frames, drive.graph, drive.initial, sampling="lossless", threads=args.threads).poses,
    }
    ate = {name: carat.ate(poses, drive.truth)["rmse"] for name, poses in runs.items()}

    fig, (top, errors) = plt.subplots(1, 2, figsize=(13, 6))
    top.plot(drive.truth[:, 0, 3], drive.truth[:, 1, 3], "k-", lw=3, alpha=0.3, label="ground truth")
    for (name, poses), style in zip(runs.items(), ["y-", "r--", "b-.", "g-", "m:"]):
        aligned = carat.ate(poses, drive.truth)["T_reference_estimate"] @ poses
        top.plot(aligned[:, 0, 3], aligned[:, 1, 3], style, label=f"{name}: ATE {ate[name]:.3f} m")
        error = np.linalg.norm(aligned[:, :3, 3] - drive.truth[:, :3, 3], axis=1)
        errors.semilogy(np.maximum(error, 1e-5), style, label=name)
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_aspect("equal")
    top.set_title(f"top view: {args.frames} frames, {len(drive.graph)} factors")
    top.legend(loc="center", fontsize=8)
    errors.set_xlabel("frame")
    errors.set_ylabel("position error after alignment (m)")
    errors.set_title(f"carat {carat.__version__}: error per frame")
    errors.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)

    print(json.dumps({"out": args.out, "frames": args.frames, "factors": len(drive.graph),
                      "simulate_s": round(simulate_s, 3), "ate_rmse_m": ate}, indent=2))
    initial = ate["initial guess (GICP odometry)"]
    best = min(ate["global registration, exact M = 29"], ate["global registration, lossless"])
    if not best < 0.5 * initial:
        print(f"global registration (ATE {best:.3f} m) did not beat the initial guess ({initial:.3f} m)", file=sys.stderr)
        return 1
    with open(args.out, "rb") as png:
        if png.read(8) != b"\x89PNG\r\n\x1a\n":
            print(f"{args.out}: not a PNG", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
