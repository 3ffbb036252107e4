"""The time offset's sums of cross-spectra (cvstereo.rigcheck.time_offset.cross_spectra) against a plain loop."""

from __future__ import annotations

import numpy as np

from cvstereo.rigcheck.time_offset import RowSpectra, cross_spectra


def _spectra(rng, frames, rows, n_freq, present):
    """Random spectra of the rows that are present (index -1 elsewhere), as _row_spectra lays them out."""
    index = np.full((frames, rows), -1, np.int64)
    index[present] = np.arange(int(present.sum()))
    spectra = (rng.normal(size=(int(present.sum()), n_freq)) + 1j * rng.normal(size=(int(present.sum()), n_freq)))
    return RowSpectra(spectra.astype(np.complex64), index, np.ones((frames, rows), np.float32))


def test_sums_the_products_of_the_rows_present_in_both(rng):
    frames, rows, n_freq = 6, 9, 17
    a = _spectra(rng, frames, rows, n_freq, rng.random((frames, rows)) < 0.6)
    b = _spectra(rng, frames, rows, n_freq, rng.random((frames, rows)) < 0.6)
    frames_a, frames_b = np.array([0, 2, 5, 5, 1]), np.array([1, 2, 0, 3, 4])
    got = cross_spectra(a, frames_a, b, frames_b, 2, 8)
    expected = np.zeros((frames_a.size, n_freq), np.complex128)
    for j, (fa, fb) in enumerate(zip(frames_a, frames_b, strict=True)):
        for y in range(2, 8):
            if a.index[fa, y] >= 0 and b.index[fb, y] >= 0:
                expected[j] += a.spectra[a.index[fa, y]] * np.conj(b.spectra[b.index[fb, y]])
    assert got.dtype == np.complex128
    # The products in single precision (the compiled one may fuse a multiply and an add), summed in double.
    np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-6)
    assert np.abs(expected).sum() > 0
    none = cross_spectra(a, frames_a, _spectra(rng, frames, rows, n_freq, np.zeros((frames, rows), bool)),
                         frames_b, 0, rows)
    assert not none.any()
