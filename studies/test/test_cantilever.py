"""The steel cantilever on a shaker (issue 9): Euler-Bernoulli model from its dimensions,
mode identification from force/acceleration records, single-effect diagnosis."""
import json

import numpy as np
import pytest
import scipy.signal as sig

from flex_model.arm import load_arm
from studies.cantilever import (DATA_SET, LBF, MODE_BANDS_HZ, REPORTED_MODES_HZ, ShakerRecord,
                                clamped_free_roots, euler_bernoulli_clamped_free_hz, frf_h1,
                                identify_modes, main, read_data_set)
from studies.modal_diagnosis import (ModalSetup, diagnose, link_totals, modal_frequencies,
                                     shift_pattern, standard_candidates)

REPORTED = np.array(REPORTED_MODES_HZ)


def test_model_modes_match_the_closed_form_euler_bernoulli_cantilever():
    """beta_n L = 1.8751, 4.6941, 7.8548 (cos x cosh x = -1); flex_model's clamped modes
    of the 759 x 50.66 x 5.14 mm steel beam within 1e-4 of f_n = (beta_n L)^2 / (2 pi L^2)
    sqrt(EI / m)."""
    assert clamped_free_roots(3) == pytest.approx([1.8751, 4.6941, 7.8548], abs=1e-4)
    arm = load_arm("usc_cantilever")
    length, mass, ei = link_totals(arm)
    assert ei == pytest.approx(2e11 * 0.05066 * 0.00514 ** 3 / 12, rel=1e-9)
    closed = euler_bernoulli_clamped_free_hz(ei, mass / length, length, 3)
    assert closed == pytest.approx([7.2751, 45.592, 127.66], rel=1e-4)
    model = modal_frequencies(ModalSetup(arm), 3)
    assert model == pytest.approx(closed, rel=1e-4)
    # the model is 9-10 % high in every mode (issue 9: "about 9 % high in all three")
    ratio = model / REPORTED
    assert ratio == pytest.approx([1.0990, 1.1014, 1.0866], abs=5e-4)


@pytest.mark.parametrize("fn, zeta", [(6.62, 0.1), (41.4, 0.01), (117.5, 0.005),
                                      (6.62, 0.01)])
def test_identification_recovers_a_known_mode(fn, zeta):
    """A single mode (accelerance -w^2 / (w_n^2 - w^2 + 2 i zeta w_n w), zero-order hold,
    exact poles) driven by random force, 19.7 s at 3200 Hz like the records, 1 % output
    noise: frequency within 0.2 %, damping ratio within 15 %. A 6.62 Hz mode with 1 %
    damping (half-power width 0.13 Hz) is not resolved by 19.7 s records: reported so."""
    rng = np.random.default_rng(1)
    fs, n = 3200.0, 63041
    force = rng.standard_normal(n)
    wn = 2 * np.pi * fn
    b, a = sig.cont2discrete(([-1.0, 0.0, 0.0], [1.0, 2 * zeta * wn, wn ** 2]), 1 / fs,
                             method="zoh")[:2]
    acc = sig.lfilter(b.ravel(), a, force)
    acc += 0.01 * acc.std() * rng.standard_normal(n)
    t = np.arange(n) / fs
    band = next(bd for bd in MODE_BANDS_HZ if bd[0] < fn < bd[1])
    peak, = identify_modes(ShakerRecord("synthetic", t, force, force, acc), [band])
    if fn * zeta < 0.1:       # half-power width 2 zeta f below 3 bins of the finest Welch
        assert not peak.identified and "not resolved" in peak.reason
        return
    assert peak.identified, peak.reason
    assert peak.frequency_hz == pytest.approx(fn, rel=2e-3)
    assert peak.damping_ratio == pytest.approx(zeta, rel=0.15)


def test_shaker_records_are_narrowband_and_show_no_resonance(shared_dir):
    """The stored records (sines at 100, 120, 150 Hz) give a coherent FRF only at the
    forcing lines, where it is the same in all three tests (a linear beam); no band around
    the reported modes holds a resolved, coherent resonance."""
    records = read_data_set(shared_dir / "data" / "real" / DATA_SET)
    assert [r.rate for r in records] == pytest.approx([3200.0] * 3, rel=1e-9)
    lines = []
    for rec in records:
        frf = frf_h1(rec)
        k = [int(np.argmin(np.abs(frf.frequency - f))) for f in (100.0, 120.0, 150.0)]
        assert np.all(frf.coherence[k] > 0.99)
        lines.append(np.abs(frf.H[k]))
        assert not any(p.identified for p in identify_modes(rec))
    lines = np.array(lines)
    assert np.ptp(lines, axis=0) / lines.mean(axis=0) == pytest.approx([0, 0, 0], abs=0.1)
    # |H| at 100 Hz: 0.055-0.060 (m/s^2)/N, i.e. 0.025-0.027 g/lbf
    assert lines[:, 0] == pytest.approx(0.057, abs=0.003)
    assert lines[:, 0] * LBF / 9.80665 == pytest.approx(0.026, abs=0.0015)


def test_diagnosis_puts_stiffness_and_mass_in_one_class_ahead_of_root_compliance():
    """Stiffness and mass scales fit the three modes equally (f ~ sqrt(EI/m)): the fitted
    EI scale is exp(-2 mean ln(f_model/f_measured)); they are indistinguishable by any
    number of frequencies, and they fit better than a compliant root or a tip mass, whose
    signatures are uniform only to first order."""
    setup = ModalSetup(load_arm("usc_cantilever", 12))
    names = ("stiffness scale", "mass scale", "root compliance")
    cands = [c for c in standard_candidates(setup) if c.name in names]
    diag = diagnose(setup, cands, REPORTED, sigma=0.005, count=4, pair=False)
    model = modal_frequencies(setup, 3)
    by = {f.name: f for f in diag.fits}
    s_closed = np.exp(-2 * np.mean(np.log(model / REPORTED)))
    assert by["stiffness scale"].values[0] == pytest.approx(s_closed, rel=1e-5)
    assert by["mass scale"].values[0] == pytest.approx(1 / s_closed, rel=1e-5)
    assert {diag.fits[k].name for k in diag.classes[0]} == {"stiffness scale", "mass scale"}
    assert [{diag.fits[a].name, diag.fits[b].name} for a, b in diag.indistinguishable] == \
        [{"stiffness scale", "mass scale"}]
    assert by["root compliance"].chi2 > 1.5 * by["stiffness scale"].chi2
    # root compliance sized to explain mode 1 (-9 %) lowers modes 2, 3 by less
    rc = next(c for c in cands if c.name == "root compliance")
    shifts = shift_pattern(setup, rc, REPORTED[0]).predicted_hz / model - 1
    assert shifts[0] == pytest.approx(REPORTED[0] / model[0] - 1, abs=1e-6)
    assert shifts == pytest.approx([-0.090, -0.078, -0.069], abs=2e-3)


@pytest.mark.parametrize("effect, size", [("root compliance", 400.0), ("tip mass", 1e-3)])
def test_root_spring_and_tip_mass_shift_all_modes_alike_to_first_order(effect, size):
    """A uniform cantilever's modes all store the same share of strain energy in a root
    spring, 4 EI / (kp L), and of kinetic energy in a tip mass, 4 M / (m L) (phi''(0) =
    2 beta^2, phi(L)^2 = 4 with int phi^2 = L): every mode drops by half of it,
    delta f / f = -2 EI / (kp L) or -2 M / (m L), here -0.5 % and -0.2 %."""
    setup = ModalSetup(load_arm("usc_cantilever", 16))
    length, mass, ei = link_totals(setup.arm)
    cand = next(c for c in standard_candidates(setup) if c.name == effect)
    if effect == "root compliance":
        value, expected = size * ei / length, -2.0 / size
    else:
        value, expected = size * mass, -2.0 * size
    shifted = modal_frequencies(cand.apply(setup, value), 3)
    assert shifted / modal_frequencies(setup, 3) - 1 == pytest.approx([expected] * 3, rel=0.05)


def test_cantilever_command_reports_the_equivalence_class(shared_dir, tmp_path, capsys):
    one = tmp_path / "data"       # one record (a link, not a copy) keeps the test short
    one.mkdir()
    name = "data_set_1_downsampled_by_16.lvm"
    (one / name).symlink_to(shared_dir / "data" / "real" / DATA_SET / name)
    args = ["--data", str(one), "--vars", "8", "--out", str(tmp_path), "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model_over_measured"] == pytest.approx(
        np.array(out["model_hz"][:3]) / REPORTED, rel=1e-12)
    assert set(out["diagnosis"]["classes"][0]) == {"stiffness scale", "mass scale"}
    report = (tmp_path / "report.md").read_text()
    assert "one equivalence class" in report and "F-test" in report
    assert (tmp_path / "cantilever.png").stat().st_size > 20_000
    assert main(["--data", str(tmp_path / "missing")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
