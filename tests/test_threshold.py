"""Hard thresholding, gamma mapping and the `analyze` experiment."""

import csv

import numpy as np
import pytest

from sparselt.analysis.threshold import (
    gamma_map,
    hard_threshold_image,
    inverse_gamma_map,
    largest_coefficients,
)
from sparselt.experiments.sparsity_analysis import analyze_signal
from sparselt.fourier import fft
from sparselt.fourier.sparse import partner_indices
from sparselt.signal import Signal


def _signal_data(seed=0, shape=(16, 12, 4, 4)):
    rng = np.random.default_rng(seed)
    # Smooth image-plane structure plus heavy-tailed detail, like rendered light transport.
    x = np.linspace(0, 1, shape[0])[:, None, None, None]
    y = np.linspace(0, 1, shape[1])[None, :, None, None]
    base = 0.5 + 0.4 * np.sin(6 * x) * np.cos(4 * y) + np.zeros(shape)
    detail = rng.pareto(3.0, size=shape) * 0.05
    data = np.stack([base + detail, 0.8 * base + detail, 0.5 * base + detail], axis=-1)
    return data.astype(np.float32)


@pytest.mark.parametrize("gamma", [1.0, 0.5, 0.25, 0.1, 0.05, 2.0])
def test_gamma_mapping_round_trip(gamma):
    data = _signal_data(1).astype(np.float64)
    mapped = gamma_map(data, gamma)
    assert mapped.min() >= 0 and mapped.max() == pytest.approx(1.0)
    assert np.allclose(inverse_gamma_map(mapped, gamma, data.max()), data, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("arguments, error, message", [
    ((np.ones(4), 0.0), ValueError, "gamma"),
    ((np.ones(4), -0.5), ValueError, "gamma"),
    ((np.ones(4), float("nan")), ValueError, "gamma"),
    ((np.ones(4), float("inf")), ValueError, "gamma"),
    ((np.ones(4), True), ValueError, "gamma"),
    ((np.array([1.0, -1.0]), 0.5), ValueError, "non-negative"),
], ids=["gamma-zero", "negative-gamma", "nan-gamma", "infinite-gamma", "boolean-gamma", "negative-values"])
def test_gamma_map_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        gamma_map(*arguments)


@pytest.mark.parametrize("arguments, error, message", [
    ((_signal_data(), 0.0), ValueError, r"\(0, 1\]"),
    ((_signal_data(), -0.1), ValueError, r"\(0, 1\]"),
    ((_signal_data(), 1.5), ValueError, r"\(0, 1\]"),
    ((_signal_data(), float("nan")), ValueError, r"\(0, 1\]"),
], ids=["fraction-zero", "negative-fraction", "fraction-above-one", "nan-fraction"])
def test_hard_threshold_image_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        hard_threshold_image(*arguments)


@pytest.mark.parametrize("gamma", [1.0, 0.3])
def test_keeping_every_coefficient_gives_the_signal_image(gamma):
    data = _signal_data(2)
    image = hard_threshold_image(data, 1.0, gamma=gamma)
    assert np.allclose(image, data.astype(np.float64).mean(axis=(2, 3)), atol=2e-6)


def test_largest_coefficients_are_the_largest_and_pair_closed():
    rng = np.random.default_rng(4)
    spectrum = fft.fftn(rng.random((10, 8, 6)))
    energy = np.abs(spectrum.ravel()) ** 2
    for count in (1, 5, 17, 100):
        kept = largest_coefficients(spectrum, count)
        assert kept.size in (count, count - 1)  # the top-K rule of sparselt.fourier.hermitian
        assert set(partner_indices(spectrum.shape, kept)) == set(kept)
        dropped = np.setdiff1d(np.arange(energy.size), kept)
        assert energy[kept].min() >= energy[dropped].max() * (1 - 1e-9)


def test_thresholded_image_error_falls_to_zero():
    data = _signal_data(3)
    full = data.astype(np.float64).mean(axis=(2, 3))
    errors = [np.abs(hard_threshold_image(data, fraction) - full).mean() for fraction in (0.001, 0.01, 0.1, 0.5, 1.0)]
    assert errors[-1] < 1e-6 and errors[0] > errors[2] > errors[-1]


def test_analyze_writes_the_tables_and_figures(tmp_path):
    data = _signal_data(5, shape=(24, 20, 4, 4))
    signal = Signal(data=data, kind="dof", axes=("x", "y", "lens_u", "lens_v"), meta={"scene": "synthetic"})
    result = analyze_signal(signal, tmp_path, gammas=(1.0, 0.5), fractions=(0.01, 0.1, 1.0), progress=False)
    for name in ("gini.csv", "table_5_1_fourier.md", "table_5_2_canonical.md", "table_7_gamma.md", "ssim.csv",
                 "ssim_vs_fraction.png", "thresholded.png", "analysis.json"):
        assert (tmp_path / name).exists(), name
    with open(tmp_path / "ssim.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 6
    full = [float(row["ssim"]) for row in rows if float(row["fraction"]) == 1.0]
    assert all(abs(value - 1.0) < 1e-6 for value in full)
    assert len(result["gini"]) == 2 * 4 * 3
    assert all(0.0 <= row[4] <= 1.0 for row in result["gini"])
    # Gamma < 1 compresses the range: the canonical (PSS) domain becomes denser.
    time_gini = {row[0]: row[4] for row in result["gini"] if row[1] == "canonical" and not row[2] and row[3] == "R"}
    assert time_gini[0.5] < time_gini[1.0]


@pytest.mark.parametrize("arguments, error, message", [
    (dict(gammas=(0.0,)), ValueError, "gamma"),
    (dict(fractions=(2.0,)), ValueError, "fraction"),
    (dict(gammas=()), ValueError, "gamma"),
], ids=["gamma-zero", "fraction-above-one", "no-gammas"])
def test_analyze_signal_invalid_input(tmp_path, arguments, error, message):
    signal = Signal(data=_signal_data(), kind="dof", axes=("x", "y", "lens_u", "lens_v"))
    with pytest.raises(error, match=message):
        analyze_signal(signal, tmp_path, progress=False, **arguments)
