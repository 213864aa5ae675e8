"""Every example script runs as a user would run it and prints what it promises: the demo as a process (the
README's command), the others as their own ``__main__`` in this process (the ``run_script`` fixture)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture
def run(run_script):
    return lambda script, *args, cwd: run_script(EXAMPLES / script, *args, cwd=cwd)


def test_demo_prints_both_models_agreement_and_writes_chart(tmp_path):
    proc = subprocess.run([sys.executable, str(EXAMPLES / "demo.py"), "--out", str(tmp_path / "chart.png")],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "model 'mass-spring-damper'" in out and "model 'series-RLC'" in out
    assert "L = " in out and "Derivative(q_L(t), (t, 2))" in out
    gap = float(re.search(r"max \|x\(t\) − q\(t\)\|\s+= (\S+)", out).group(1))
    exact = re.search(r"max \|x − exact\| = (\S+), max \|q − exact\| = (\S+)", out)
    assert gap < 1e-9
    assert float(exact.group(1)) < 1e-6 and float(exact.group(2)) < 1e-6
    png = (tmp_path / "chart.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000
    # ngspice agrees with the circuit and with the mechanism's derived analogue to < 1e-6 of the peak
    rel = [float(x) for x in re.findall(r"^\s+[iv]\(\w+\)\s.*\s(\S+)$", out, re.M)]
    assert len(rel) == 4 and max(rel) < 1e-6
    for suffix in ("circuit", "mechanism"):
        assert (tmp_path / f"chart-ngspice-{suffix}.png").read_bytes().startswith(b"\x89PNG")


def test_two_mass_chain_finds_golden_ratio_frequencies(run, tmp_path):
    out = run("two_mass_chain.py", cwd=tmp_path)
    freqs = [float(x) for x in re.search(r"normal-mode frequencies: \[([^\]]+)\]", out).group(1).split()]
    assert freqs == pytest.approx([(5**0.5 - 1) / 2, (5**0.5 + 1) / 2], rel=1e-7)  # printed to 8 decimals


def test_parallel_rlc_amplitude_matches_impedance(run, tmp_path):
    out = run("parallel_rlc_flux.py", cwd=tmp_path)
    sim, z = map(float, re.search(r"simulated (\S+) V, \|Z\|·I = (\S+) V", out).groups())
    assert sim == pytest.approx(z, rel=1e-4)


def test_duffing_plugin_periods_match_quadrature(run, tmp_path):
    out = run("duffing_plugin.py", cwd=tmp_path)
    pairs = re.findall(r"period simulated (\S+), quadrature (\S+)", out)
    assert len(pairs) == 3
    for sim, quad in pairs:
        assert float(sim) == pytest.approx(float(quad), rel=1e-5)


def test_impulses_match_the_notes_closed_forms(run, tmp_path):
    out = run("impulses.py", "--out", str(tmp_path / "impulses.png"), cwd=tmp_path)
    assert out.count("symbolic agreement: True") == 2  # four-bar velocities; knife edge velocities and energy
    assert "Q_x1 = F, Q_theta = 2*F*b*sin(theta)" in out
    assert "y_c' = v*(4*e - 3)/7, theta' = 6*v*(e + 1)/(7*L)" in out
    before, after = re.search(r"angular momentum about the edge: before (\S+), after (\S+)", out).groups()
    assert before == after
    errors = [float(x) for x in re.findall(r"max \|error\| = (\S+)", out)]
    assert len(errors) == 2 and max(errors) < 1e-12
    assert "velocity of the point 2*ell/3 from the struck end: 0" in out
    assert "theta1' = 0, theta2' = P/(l2*m2)" in out
    assert (tmp_path / "impulses.png").read_bytes().startswith(b"\x89PNG")


def test_impacts_follow_the_closed_forms_and_come_to_rest(run, tmp_path):
    out = run("impacts.py", "--out", str(tmp_path / "impacts.png"), cwd=tmp_path)
    errors = [float(x) for x in re.findall(r"max \|t_\w − closed form\|.* = (\S+) s", out)]
    assert len(errors) == 2 and max(errors) < 1e-9
    assert float(re.search(r"max \|energy lost − .*\| = (\S+) J", out).group(1)) < 1e-9
    gap = float(re.search(r"\(\|difference\| (\S+) s\)", out).group(1))
    assert gap < 1e-3
    height, speed = map(float, re.search(r"height (\S+) m, velocity (\S+) m/s", out).groups())
    assert abs(height) < 1e-9 and abs(speed) < 1e-9
    ratios = [float(x) for x in re.findall(r"omega after/before = (\S+)", out)]
    assert len(ratios) == 5 and all(abs(r + 0.8) < 1e-9 for r in ratios)
    assert (tmp_path / "impacts.png").read_bytes().startswith(b"\x89PNG")


# -- the frequency domain ---------------------------------------------------------------------------------


def test_loudspeaker_impedance_three_ways_agree_with_the_closed_form(run, tmp_path):
    out = run("loudspeaker_impedance.py", "--out", str(tmp_path / "z.png"), cwd=tmp_path)
    diffs = [float(x) for x in re.findall(r"max \|Z/Z_closed − 1\| = (\S+)", out)]
    assert len(diffs) == 3 and max(diffs) < 1e-9  # Lagrangian, mechanical view, ngspice's equivalent circuit
    peak = float(re.search(r"\|Z\(f_s\)\| from the Lagrangian = (\S+) Ω", out).group(1))
    ws = (2000.0 / 0.02) ** 0.5  # at f_s the cone's impedance is c: |Z| = |Re + Bl²/c + j ωs Le|
    assert peak == pytest.approx(abs(6.0 + 7.0**2 / 1.5 + 1j * ws * 0.5e-3), rel=1e-6)
    assert (tmp_path / "z.png").read_bytes().startswith(b"\x89PNG")


def test_isolator_transmissibility_matches_the_closed_form(run, tmp_path):
    out = run("isolator_transmissibility.py", "--out", str(tmp_path / "t.png"), cwd=tmp_path)
    assert float(re.search(r"max relative difference from the closed form: (\S+)", out).group(1)) < 1e-12
    crossings = [float(x) for x in re.findall(r"\|T\| at r = √2: (\S+);", out)]
    assert len(crossings) == 4 and all(abs(c - 1) < 1e-12 for c in crossings)  # every damping crosses 1 at r = √2


def test_ladder_filter_bode_is_butterworth_and_agrees_with_ngspice(run, tmp_path):
    out = run("ladder_filter_bode.py", "--out", str(tmp_path / "b.png"), cwd=tmp_path)
    assert float(re.search(r"closed form − 1 at the load: (\S+)", out).group(1)) < 1e-9
    assert float(re.search(r"\): (\S+) dB from the passband", out).group(1)) == pytest.approx(-3.0103, abs=1e-4)
    assert float(re.search(r"roll-off .*: (\S+) dB per decade", out).group(1)) == pytest.approx(-100, abs=0.01)
    assert float(re.search(r"worst relative difference (\S+)", out).group(1)) < 1e-9


def test_coupled_tanks_modes_are_the_closed_form_in_both_formulations(run, tmp_path):
    out = run("coupled_tanks_modes.py", "--out", str(tmp_path / "c.png"), cwd=tmp_path)
    diffs = [float(x) for x in re.findall(r"max rel\. difference (\S+)\)", out)]
    assert len(diffs) == 2 and max(diffs) < 1e-12
    assert out.count("(+1.000, +1.000), (+1.000, -1.000)") == 2


def test_stability_map_agrees_with_the_closed_form_boundary(run, tmp_path):
    out = run("stability_map.py", "--points", "4", "--serial", "--out", str(tmp_path / "s.png"), cwd=tmp_path)
    agree, total = map(int, re.search(r"stable where Ω² l < g in (\d+) of (\d+) samples", out).groups())
    assert total == 16 and agree == total
    assert "16 done, 0 failed" in out and (tmp_path / "s.png").stat().st_size > 1000


def test_bicycle_finds_the_papers_weave_and_capsize_speeds_and_a_nudge_dies_away(run, tmp_path):
    out = run("bicycle.py", "--out", str(tmp_path / "bike.png"), cwd=tmp_path)
    weave, capsize = (float(x) for x in re.findall(r"(?:weave|capsize) speed\s+(\S+) m/s", out))
    assert weave == pytest.approx(4.29238253634111, abs=1e-12)  # Meijaard et al. (2007), Table 2
    assert capsize == pytest.approx(6.02426201538837, abs=1e-12)
    offs = [float(x) for x in re.findall(r"paper \S+\s+off (\S+)", out)]
    assert len(offs) == 5 and max(offs) < 1e-12  # three eigenvalues at 5 m/s, two speeds
    peak, after, drift = (float(x) for x in re.search(
        r"lean peaks at (\S+) rad, (\S+) rad after 6 s; energy kept to (\S+)", out).groups())
    assert after < 0.1 * peak and drift < 1e-9
    assert (tmp_path / "bike.png").stat().st_size > 10_000


def test_travel_pickles_saves_exports_and_converts_the_double_pendulum(run, tmp_path):
    out = run("travel.py", "--out", str(tmp_path / "travel.png"), "--dir", str(tmp_path), cwd=tmp_path)
    assert out.count("bit for bit the same run: True") == 2  # pickled, and through the model file
    fmu = float(re.search(r"FMPy's run against ours: (\S+) of the peak", out).group(1))
    bode = float(re.search(r"Bode response against ours: (\S+)", out).group(1))
    assert fmu < 1e-7 and bode < 1e-12
    assert (tmp_path / "double_pendulum.fmu").stat().st_size > 1000
    assert (tmp_path / "travel.png").stat().st_size > 10_000


def test_fit_loudspeaker_flags_the_free_air_ambiguity_and_recovers_the_truth_with_an_added_mass(run, tmp_path):
    out = run("fit_loudspeaker.py", "--out", str(tmp_path / "fit.png"), cwd=tmp_path)
    assert "do not determine Bl_coil, m_m, k_k, c_c separately" in out.split("free air and +10 g:")[0]
    verdicts = re.findall(r"fitted \S+ \((\S+) off\), in its 3σ interval: (\w+)", out)
    assert len(verdicts) == 6 and all(v == "True" and float(off) < 1e-2 for off, v in verdicts)
    assert (tmp_path / "fit.png").read_bytes().startswith(b"\x89PNG")
