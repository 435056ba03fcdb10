"""carat.coreset: exact H = J^T J, b = J^T e, c = e^T e, checked in numpy."""

import numpy as np
import pytest

import carat


def model(J, e, w=None):
    w = np.ones(len(e)) if w is None else w
    return (J.T * w) @ J, (J.T * w) @ e, float(w @ (e * e))


def assert_exact(J, e, idx, w, tol=1e-12):
    H, b, c = model(J, e)
    Hs, bs, cs = model(J[idx], e[idx], w)
    assert np.abs(Hs - H).max() <= tol * np.abs(H).max()
    assert np.abs(bs - b).max() <= tol * max(np.abs(b).max(), np.abs(H).max())
    assert abs(cs - c) <= tol * c


@pytest.mark.parametrize("D", [2, 6, 12])
def test_exact_for_every_dimension(D):
    rng = np.random.default_rng(D)
    N = 30000
    J = rng.normal(size=(N, D)) * rng.uniform(0.1, 10, size=D)
    e = rng.normal(size=N) + 0.5
    idx, w = carat.coreset(J, e)
    L = D * (D + 1) // 2 + D + 1
    assert len(idx) == L + 1 == carat.minimum_coreset_rows(D)
    assert idx.dtype == np.int64 and np.all(np.diff(idx) > 0)
    assert np.all(w > 0)
    assert_exact(J, e, idx, w)


def test_target_seed_and_default_size():
    rng = np.random.default_rng(1)
    J = rng.normal(size=(4000, 6))
    e = rng.normal(size=4000)
    idx, _ = carat.coreset(J, e)
    assert len(idx) == 29
    idx40, w40 = carat.coreset(J, e, target=40, seed=3)
    assert len(idx40) == 40
    assert_exact(J, e, idx40, w40)
    again, _ = carat.coreset(J, e, target=40, seed=3)
    assert np.array_equal(idx40, again)
    other, _ = carat.coreset(J, e, target=40, seed=4)
    assert not np.array_equal(idx40, other)


def test_layouts_and_dtypes_give_the_same_rows():
    rng = np.random.default_rng(2)
    J = rng.normal(size=(6000, 6))
    e = rng.normal(size=6000)
    reference = carat.coreset(J[::2].copy(), e[::2].copy())
    strided = carat.coreset(J[::2], e[::2])  # not contiguous: converted
    assert np.array_equal(reference[0], strided[0]) and np.array_equal(reference[1], strided[1])
    fortran = carat.coreset(np.asfortranarray(J[::2]), e[::2])
    assert np.array_equal(reference[0], fortran[0])
    ints = np.rint(J * 100).astype(np.int32)
    idx, w = carat.coreset(ints, e)
    assert_exact(ints.astype(float), e, idx, w)
    column = carat.coreset(J, e.reshape(-1, 1))
    assert np.array_equal(column[0], carat.coreset(J, e)[0])


def test_few_rows_are_kept_whole():
    J = np.arange(12.0).reshape(6, 2)
    e = np.ones(6)
    idx, w = carat.coreset(J, e)
    assert idx.tolist() == list(range(6)) and np.all(w == 1.0)


def test_bad_input_raises():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(1000, 6))
    e = rng.normal(size=1000)
    bad = J.copy()
    bad[17, 3] = np.nan
    with pytest.raises(carat.Error, match="row 17 has a non-finite"):
        carat.coreset(bad, e)
    bad_e = e.copy()
    bad_e[5] = np.inf
    with pytest.raises(carat.Error, match="row 5"):
        carat.coreset(J, bad_e)
    with pytest.raises(ValueError, match="e: expected 1000 residuals"):
        carat.coreset(J, e[:-1])
    with pytest.raises(ValueError, match="J: expected an N x D array"):
        carat.coreset(e, e)
    with pytest.raises(TypeError, match="J: expected an array of numbers"):
        carat.coreset("rows", e)
    with pytest.raises(TypeError, match="dtype"):
        carat.coreset(J.astype(complex), e)
    with pytest.raises(carat.Error, match="29"):
        carat.coreset(J, e, target=20)
    with pytest.raises(ValueError, match=r"J: at most 128 columns .*got 140000"):
        carat.coreset(np.ones((3, 140000)), np.ones(3))
    with pytest.raises(ValueError, match=r"columns: must be in \[1, 128\], got 0"):
        carat.minimum_coreset_rows(0)
    with pytest.raises(ValueError, match=r"e: expected 1000 residuals \(one per row of J\), got shape \(1000, 1, 1\)"):
        carat.coreset(J, e[:, None, None])
    assert np.array_equal(carat.coreset(J, e, clusters=0)[0], carat.coreset(J, e)[0])
    with pytest.raises(ValueError, match="J: no rows"):
        carat.coreset(np.zeros((0, 6)), np.zeros(0))
    assert issubclass(carat.Error, RuntimeError)
