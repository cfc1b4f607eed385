"""Krippendorff's alpha against the worked examples of Krippendorff (2011)."""

import numpy as np
import pytest

from analysis.agreement import krippendorff_alpha

NAN = np.nan
# "Computing Krippendorff's Alpha-Reliability" (2011), section C: 4 observers x 12 units,
# values 1..5, blanks missing. Published: nominal 0.743, ordinal 0.815, interval 0.849.
RELIABILITY_DATA = np.array([
    [1, 2, 3, 3, 2, 1, 4, 1, 2, NAN, NAN, NAN],
    [1, 2, 3, 3, 2, 2, 4, 1, 2, 5, NAN, 3],
    [NAN, 3, 3, 3, 2, 3, 4, 2, 2, 5, 1, NAN],
    [1, 2, 3, 3, 2, 4, 4, 1, 2, 5, 1, NAN],
])


def long_form(data):
    units = np.tile(np.arange(data.shape[1]), data.shape[0])
    return units, data.ravel()


@pytest.mark.parametrize("level, published", [("nominal", 0.743), ("ordinal", 0.815), ("interval", 0.849)])
def test_krippendorffs_worked_example(level, published):
    result = krippendorff_alpha(*long_form(RELIABILITY_DATA), level=level)
    assert result["alpha"] == pytest.approx(published, abs=5e-4)
    # Unit 12 has a single value: it cannot be paired and is left out.
    assert result["n_units"] == 11 and result["n_values"] == 40


def test_two_observers_binary_example():
    # Section A of the same paper: two observers, ten units, alpha = 0.095.
    a = [0, 1, 0, 0, 0, 0, 0, 0, 1, 0]
    b = [1, 1, 1, 0, 0, 1, 0, 0, 0, 0]
    result = krippendorff_alpha(np.tile(np.arange(10), 2), np.array(a + b), level="nominal")
    assert result["alpha"] == pytest.approx(0.095, abs=5e-4)


@pytest.mark.parametrize("level", ["nominal", "ordinal", "interval"])
def test_matches_the_krippendorff_package(level):
    krippendorff = pytest.importorskip("krippendorff")
    rng = np.random.default_rng(1)
    data = rng.integers(1, 6, size=(5, 40)).astype(float)
    data[rng.random(data.shape) < 0.3] = np.nan
    ours = krippendorff_alpha(*long_form(data), level=level)["alpha"]
    assert ours == pytest.approx(krippendorff.alpha(reliability_data=data, level_of_measurement=level))


def test_perfect_agreement_and_bootstrap_interval():
    units = np.repeat(np.arange(20), 3)
    values = np.repeat(np.arange(20) % 4, 3)
    result = krippendorff_alpha(units, values, "ordinal", bootstrap=100)
    assert result["alpha"] == pytest.approx(1.0)
    assert result["ci_low"] == pytest.approx(1.0) and result["ci_high"] == pytest.approx(1.0)
    noisy = krippendorff_alpha(*long_form(RELIABILITY_DATA), "ordinal", bootstrap=300)
    assert noisy["ci_low"] < noisy["alpha"] < noisy["ci_high"]


def test_undefined_without_pairable_values_or_variation():
    assert np.isnan(krippendorff_alpha([1, 2, 3], [1, 2, 3])["alpha"])
    assert krippendorff_alpha([1, 2, 3], [1, 2, 3])["n_units"] == 0
    assert np.isnan(krippendorff_alpha([1, 1, 2, 2], [3, 3, 3, 3])["alpha"])
    with pytest.raises(ValueError, match="unknown level"):
        krippendorff_alpha([1, 1], [1, 2], level="ratio")
