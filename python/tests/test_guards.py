"""The module's guards match the CLI's: integer arguments named when out of range, sizes the
machine cannot hold refused before any work with the same estimates, frames tied to nothing,
odometry that cannot be trusted, and Ctrl-C inside a long coreset."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import carat


def test_out_of_range_integers_name_the_argument():
    rng = np.random.default_rng(1)
    J, e = rng.standard_normal((100, 2)), rng.standard_normal(100)
    with pytest.raises(ValueError, match=r"^seed: must be an integer in \[0, 18446744073709551615\], got -1$"):
        carat.coreset(J, e, seed=-1)
    with pytest.raises(ValueError, match=r"^target: must be an integer in \[-2147483648, 2147483647\], got 1099511627776$"):
        carat.coreset(J, e, target=2**40)
    with pytest.raises(ValueError, match=r"^frames: must be an integer in"):
        carat.simulate_scans(frames=2**40)
    with pytest.raises(ValueError, match=r"^seed: must be an integer in \[0, 18446744073709551615\], got 18446744073709551616$"):
        carat.simulate(frames=4, seed=2**64)
    with pytest.raises(ValueError, match=r"^max_points: must be an integer in \[0, 18446744073709551615\], got -5$"):
        carat.read_point_cloud("never-read.pcd", max_points=-5)
    # numpy integers are integers; floats and bools are not.
    rows, weights = carat.coreset(J, e, seed=np.uint64(3))
    assert len(rows) == carat.minimum_coreset_rows(2) and np.all(weights > 0)
    with pytest.raises(TypeError):
        carat.coreset(J, e, seed=1.5)
    with pytest.raises(TypeError):
        carat.minimum_coreset_rows(True)


def run_limited(body, headroom_mb):
    """Runs `body` in a fresh interpreter whose address space may grow by headroom_mb only."""
    script = textwrap.dedent(
        f"""
        import resource
        import numpy as np
        import carat
        size = int(next(l for l in open("/proc/self/status") if l.startswith("VmSize:")).split()[1]) * 1024
        limit = size + {headroom_mb} * 2**20
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        """
    ) + textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)


def test_sizes_the_machine_cannot_hold_are_refused_before_any_work():
    # 30,000 x 64 rows are 15 MB, but the coreset lifts them to 2,145 numbers each (about 0.8 GB).
    run = run_limited(
        """
        J = np.random.default_rng(1).standard_normal((30000, 64))
        try:
            carat.coreset(J, J[:, 0])
            print("ran")
        except ValueError as e:
            print(e)
        """,
        headroom_mb=300,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("J: the coreset of 30000 x 64 rows needs about "), run.stdout
    assert "(30000 rows lifted to 2145 numbers each)" in run.stdout
    # A million scans, priced from the first one as `carat simulate` prices the disk.
    with pytest.raises(ValueError, match=r"^frames: 1000000 frames would take about .* of memory \(.* per frame\)"):
        carat.simulate_scans(frames=10**6)


def test_optimize_refuses_frames_tied_to_nothing(small_drive):
    frames, poses = small_drive.frames[:4], small_drive.truth[:4]
    with pytest.raises(carat.Error, match=r"2 of 4 frames are tied to frame 0 by no chain of pairs \(e\.g\. frame 2; 1 pairs given\)"):
        carat.optimize(frames, np.array([[0, 1]]), poses)
    with pytest.raises(carat.Error, match=r"3 of 4 frames are tied to frame 0 by no chain of pairs \(e\.g\. frame 1; 0 pairs given\)"):
        carat.optimize(frames, np.zeros((0, 2)), poses)


def test_odometry_that_cannot_be_trusted_raises_unless_allowed():
    rng = np.random.default_rng(2)
    planes = [
        carat.Frame(np.column_stack([rng.uniform(-20, 20, 2000), rng.uniform(-20, 20, 2000), np.zeros(2000)]), name=f"plane{k}")
        for k in range(3)
    ]
    with pytest.raises(carat.Error, match=r"^odometry: 2 of 2 steps cannot be trusted, .*: plane0 -> plane1 .*; plane1 -> plane2 "):
        carat.odometry(planes)
    poses, steps = carat.odometry(planes, allow_unconverged=True, steps=True)
    assert poses.shape == (3, 4, 4)
    assert list(steps["constrained_dof"]) == [3, 3] and not steps["reliable"].any()


def test_ctrl_c_ends_a_coreset_inside_its_elimination():
    # One elimination of 3,000 points in 1,225 dimensions (D = 48): a second or more of work,
    # interrupted at 0.1 s; the interrupted call must end long before an uninterrupted one.
    script = textwrap.dedent(
        """
        import os, signal, threading, time
        import numpy as np
        import carat
        J = np.random.default_rng(3).standard_normal((3000, 48))
        start = time.monotonic()
        carat.coreset(J, J[:, 0])
        full = time.monotonic() - start
        threading.Timer(0.1, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        start = time.monotonic()
        try:
            carat.coreset(J, J[:, 0])
            print("finished")
        except KeyboardInterrupt:
            print("interrupted", time.monotonic() - start, full)
        """
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    word, interrupted, full = run.stdout.split()
    assert word == "interrupted", run.stdout
    assert float(interrupted) < 0.5 * float(full), run.stdout
