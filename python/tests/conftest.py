"""Shared fixtures of carat's Python tests."""

import os
import pathlib

import numpy as np
import pytest


@pytest.fixture(scope="session")
def data_dir():
    """The real test data (../shared/data, or CARAT_DATA_DIR); tests that need it skip without it."""
    path = pathlib.Path(
        os.environ.get("CARAT_DATA_DIR") or pathlib.Path(__file__).resolve().parents[2] / ".." / "shared" / "data"
    )
    if not path.is_dir():
        pytest.skip(f"real data not found at {path}")
    return path


@pytest.fixture(scope="session")
def small_drive():
    """A small synthetic drive (24 frames, two laps) with its dense graph, shared by the tests."""
    import carat

    return carat.simulate(frames=24, laps=2, threads=2)


def rotation_angle_deg(R):
    """Angle of a rotation matrix, degrees."""
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


def se3_exp(w, v):
    """A 4 x 4 rigid transform rotating by the axis-angle w (radians) and translating by v."""
    angle = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    R = np.eye(3)
    if angle > 0:
        K = K / angle
        R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = v
    return T
