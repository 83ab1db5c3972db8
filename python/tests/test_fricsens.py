"""Tests of the Python package: closed forms, the CLI's numbers bit for bit, errors, the GIL,
the VTK sensitivity fields read back by a real VTK reader, the scipy map and the worked
identification study."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import fricsens

ROOT = Path(__file__).resolve().parents[2]


def cli(*args: str) -> None:
    """Run the fricsens command line (FRICSENS_BIN, else the release build, else cargo)."""
    exe = os.environ.get("FRICSENS_BIN") or str(ROOT / "target" / "release" / "fricsens")
    cmd = [exe, *args] if Path(exe).exists() else [
        "cargo", "run", "--release", "--quiet", "--", *args]
    subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True)


@pytest.fixture(scope="module")
def lateral_scene(tmp_path_factory) -> Path:
    """The uniaxial J2 cube (oracles.md section 1) with a lateral displacement response: a
    nodal displacement that depends on every parameter once the cube yields."""
    text = fricsens.Scene.load("uniaxial-j2").to_toml()
    text += '\n[[responses]]\nkind = "displacement"\nname = "lateral"\nset = "cube.ymax"\ncomponent = "y"\n'
    path = tmp_path_factory.mktemp("scene") / "uniaxial-lateral.toml"
    path.write_text(text)
    return path


def test_ddm_and_the_adjoint_match_the_j2_uniaxial_closed_form():
    # oracles.md section 1: strain to eps_a = 0.01 and back to -eps_a; after the reversal
    # sigma = E (H eps - sigma_y - 2 H eps_p1) / (E + H), eps_p1 = (E eps_a - sigma_y) / (E + H)
    scene = fricsens.Scene.load("uniaxial-j2")
    E, sy, H = (scene.get(p) for p in ("E", "sigma_y", "H"))
    eps_a = eps = 0.01

    def sigma(E, sy, H):
        ep1 = (E * eps_a - sy) / (E + H)
        return E * (-H * eps - sy - 2 * H * ep1) / (E + H)

    # its derivatives by hand (d eps_p1/dE = (H eps_a + sy)/(E + H)^2, ...)
    ep1 = (E * eps_a - sy) / (E + H)
    n = -H * eps - sy - 2 * H * ep1
    exact = {
        "sigma_y": E / (E + H) * (-1 + 2 * H / (E + H)),
        "H": (-E * n / (E + H) ** 2
              + E / (E + H) * (-eps - 2 * ep1 + 2 * H * (E * eps_a - sy) / (E + H) ** 2)),
        "E": H * n / (E + H) ** 2 - E / (E + H) * 2 * H * (H * eps_a + sy) / (E + H) ** 2,
    }
    assert sigma(E, sy, H) == pytest.approx(-492.063492, rel=1e-8)  # the worked value
    assert exact["sigma_y"] == pytest.approx(-0.86167800, rel=1e-7)
    assert exact["H"] == pytest.approx(-0.022297808, rel=1e-7)
    # (oracles.md prints dsigma/dE = -2.6832978e-4, 9e-7 off its own formula: -2.68329554e-4)
    for method in ("ddm", "adjoint"):
        s = scene.sensitivity(["sigma_y", "H", "E"], method=method)
        last = -1
        assert s.times[last] == pytest.approx(3.0)
        assert s.value("stress")[last] == pytest.approx(sigma(E, sy, H), rel=1e-10)
        for p, d in exact.items():
            # radial return is exact on this path: to the solver's tolerance
            assert s.derivative("stress", p)[last] == pytest.approx(d, rel=1e-9), (method, p)


@pytest.mark.parametrize("method", ["ddm", "sdm", "fdm-central"])
def test_python_equals_the_command_line_bit_for_bit(tmp_path, lateral_scene, method):
    cli("sensitivity", str(lateral_scene), "--method", method, "--beta", "1e-6",
        "--out", str(tmp_path))
    ref = json.loads((tmp_path / "sensitivity.json").read_text())
    s = fricsens.Scene.load(str(lateral_scene)).sensitivity(
        ref["parameters"], method=method, beta=1e-6)
    assert s.parameters == ref["parameters"] and s.responses == ref["responses"]
    values = np.array([i["values"] for i in ref["increments"]])
    derivatives = np.array([i["derivatives"] for i in ref["increments"]])
    # serde_json writes the shortest text that reads back as the same double
    assert np.array_equal(s.values, values)
    assert np.array_equal(s.derivatives, derivatives)


def test_refined_sdm_equals_the_command_line_and_beats_plain_sdm(tmp_path):
    # rigid_modes=True is --rigid-modes, bit for bit; on the large-deflection cantilever's
    # length it is closer to DDM than plain SDM (0.5 beta against 1.7e3 beta measured)
    cli("sensitivity", "cantilever", "--param", "beam.length.x", "--method", "sdm",
        "--beta", "1e-4", "--rigid-modes", "--out", str(tmp_path))
    ref = json.loads((tmp_path / "sensitivity.json").read_text())
    scene = fricsens.Scene.load("cantilever")
    s = scene.sensitivity(["beam.length.x"], method="sdm", beta=1e-4, rigid_modes=True)
    assert np.array_equal(s.derivatives, np.array([i["derivatives"] for i in ref["increments"]]))
    ddm = scene.sensitivity(["beam.length.x"], method="ddm")
    plain = scene.sensitivity(["beam.length.x"], method="sdm", beta=1e-4)
    tip = ddm.derivative("tip-deflection", "beam.length.x")
    err = lambda x: np.max(np.abs(x.derivative("tip-deflection", "beam.length.x") - tip))
    assert err(s) < err(plain) / 100
    with pytest.raises(fricsens.FricsensError, match="rigid_modes"):
        scene.sensitivity(["beam.length.x"], method="ddm", rigid_modes=True)


@pytest.mark.parametrize("method", ["sdm", "fdm"])
def test_auto_steps_and_error_bars_equal_the_command_line(tmp_path, method):
    # beta="auto": the steps chosen per increment and parameter and the error bars, as the CLI
    cli("sensitivity", "jenkins", "--method", method, "--beta", "auto", "--out", str(tmp_path))
    ref = json.loads((tmp_path / "sensitivity.json").read_text())
    s = fricsens.Scene.load("jenkins").sensitivity(ref["parameters"], method=method, beta="auto")
    assert np.array_equal(s.derivatives, np.array([i["derivatives"] for i in ref["increments"]]))
    assert np.array_equal(s.error_bars, np.array([i["error_bars"] for i in ref["increments"]]))
    assert np.array_equal(s.betas, np.array([i["betas"] for i in ref["increments"]]))


def test_errors_are_python_exceptions_with_the_librarys_messages(tmp_path):
    with pytest.raises(fricsens.SceneError, match="no-such-scene"):
        fricsens.Scene.load("no-such-scene")
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[[bodies]]\nname = 3\n')
    with pytest.raises(fricsens.SceneError, match=r"bad\.toml.*line 3"):
        fricsens.Scene.load(str(bad))
    scene = fricsens.Scene.load("uniaxial-j2")
    with pytest.raises(fricsens.ParameterError, match="nope"):
        scene.sensitivity(["nope"])
    with pytest.raises(fricsens.ParameterError, match="must be > 0"):
        scene.with_values(E=-1.0)
    # a friction law's parameter is checked as a material's is
    with pytest.raises(fricsens.ParameterError, match="mu"):
        fricsens.Scene.load("strip-pullout").with_values(mu=-0.3)
    with pytest.raises(fricsens.FricsensError, match="method"):
        scene.sensitivity(["E"], method="adjoint-ish")
    # an analysis that fails: the cube compressed to minus its length inverts its element
    text = scene.to_toml().replace("value = 0.01", "value = -2.0").replace(
        'kinematics = "small"', 'kinematics = "large"')
    with pytest.raises(fricsens.AnalysisError, match=r"increment \d+ .*element 0: det F"):
        fricsens.Scene.from_toml(text).run()
    assert issubclass(fricsens.AnalysisError, fricsens.FricsensError)


def test_a_failed_analysis_carries_the_increments_that_converged():
    # the J2 cube in large kinematics, strained as the scene does over its first step (10
    # increments); right after it the prescribed end moves to minus three times the cube's
    # length, which inverts its element at any step of the second step's one increment, and
    # no cutback is allowed
    text = fricsens.Scene.load("uniaxial-j2").to_toml().replace(
        'kinematics = "small"', 'kinematics = "large"').replace(
        "amplitude = [[0.0, 0.0], [1.0, 1.0], [3.0, -1.0]]",
        "amplitude = [[0.0, 0.0], [1.0, 1.0], [1.001, -300.0]]").replace(
        "max_cutbacks = 10", "max_cutbacks = 0")
    assert "[1.001, -300.0]" in text and "max_cutbacks = 0" in text
    second = "[[steps]]\nend = 3.0\nincrements = 20\n"
    assert second in text
    failing = fricsens.Scene.from_toml(text.replace(second, "[[steps]]\nend = 2.0\nincrements = 1\n"))
    # the same scene stopped where the failing one converged last: it runs to its end
    truncated = fricsens.Scene.from_toml(text.replace(second, ""))
    whole = truncated.run()
    assert whole.times[-1] == 1.0 and len(whole.times) == 11

    with pytest.raises(fricsens.AnalysisError, match="det F") as failed:
        failing.run()
    partial = failed.value.partial
    assert isinstance(partial, fricsens.Run)
    # every converged increment, and the same numbers as the run that did not fail
    assert np.array_equal(partial.times, whole.times)
    assert np.array_equal(partial.values, whole.values)
    assert np.array_equal(partial.displacements, whole.displacements)
    assert np.array_equal(partial.contact_state, whole.contact_state)

    for method in ("ddm", "sdm", "sdm-central"):
        ref = truncated.sensitivity(["sigma_y", "H", "E"], method=method, beta=1e-6)
        with pytest.raises(fricsens.AnalysisError, match="det F") as failed:
            failing.sensitivity(["sigma_y", "H", "E"], method=method, beta=1e-6)
        s = failed.value.partial
        assert isinstance(s, fricsens.Sensitivity), method
        assert s.method == ref.method and s.parameters == ref.parameters
        assert np.array_equal(s.increments, ref.increments), method
        assert np.array_equal(s.times, ref.times), method
        assert np.array_equal(s.values, ref.values), method
        assert np.array_equal(s.derivatives, ref.derivatives), method
    # finite differences need every rerun's whole history: nothing partial to give
    with pytest.raises(fricsens.AnalysisError) as failed:
        failing.sensitivity(["E"], method="fdm")
    assert failed.value.partial is None
    # an error raised before any increment converged has none either
    with pytest.raises(fricsens.AnalysisError) as failed:
        fricsens.Scene.from_toml(text.replace("value = 0.01", "value = -2.0").replace(
            "[[steps]]\nend = 1.0\nincrements = 10\n", "[[steps]]\nend = 1.0\nincrements = 1\n")
        ).run()
    assert failed.value.partial is None


def test_runs_release_the_gil_and_report_progress():
    scene = fricsens.Scene.load("leaf-spring-coarse")
    seen = []
    done = threading.Event()
    result = {}

    def work():
        result["s"] = scene.sensitivity(["mu"], progress=lambda i, t: seen.append((i, t)))
        done.set()

    th = threading.Thread(target=work)
    th.start()
    # this thread keeps running Python while the analysis runs in Rust
    ticks = 0
    while not done.is_set():
        ticks += 1
        done.wait(0.001)
    th.join()
    s = result["s"]
    assert ticks > 10
    assert [i for i, _ in seen] == list(s.increments)
    assert np.array_equal([t for _, t in seen], s.times)


def test_vtk_sensitivity_fields_read_back_equal_the_response_derivatives(tmp_path, lateral_scene):
    meshio = pytest.importorskip("meshio")
    cli("sensitivity", str(lateral_scene), "--method", "ddm", "--vtk", "--out", str(tmp_path))
    ref = json.loads((tmp_path / "sensitivity.json").read_text())
    r = ref["responses"].index("lateral")
    checked = 0
    for inc in ref["increments"]:
        mesh = meshio.read(tmp_path / "vtk" / f"step_{inc['increment']:04d}.vtu")
        top = np.flatnonzero(np.isclose(mesh.points[:, 1], 1.0))
        assert len(top) == 4
        for k, p in enumerate(ref["parameters"]):
            field = mesh.point_data[f"d(displacement)/d({p})"]
            d = inc["derivatives"][r][k]
            # the response is the mean of the top nodes' y displacement
            assert field[top, 1].mean() == pytest.approx(d, rel=1e-12, abs=1e-300)
            checked += 1
        assert "d(equivalent_plastic_strain)/d(H)" in mesh.cell_data
        assert "equivalent_plastic_strain" in mesh.cell_data
    assert checked == len(ref["increments"]) * len(ref["parameters"])


def test_map_jacobian_is_the_derivative_of_its_value():
    scene = fricsens.Scene.load("uniaxial-j2")
    params = ["sigma_y", "H", "E"]
    m = fricsens.Map(scene, params, ["stress"])
    values = fricsens.Map(scene, params, ["stress"], method=None)
    x = np.array([scene.get(p) for p in params])
    f, j = m.value_and_jacobian(x)
    assert m.analyses == 1 and m.jac(x) is j  # the cache: one analysis per x
    assert np.array_equal(f, values.fun(x))
    for k in range(len(params)):
        h = 1e-5 * x[k]
        e = np.zeros_like(x)
        e[k] = h
        fd = (values.fun(x + e) - values.fun(x - e)) / (2 * h)
        scale = np.abs(j[:, k]).max()
        # central differences: truncation h^2 (the path is piecewise smooth) and the
        # Newton tolerance over 2h
        assert np.abs(fd - j[:, k]).max() < 1e-5 * scale, params[k]


def test_identification_study_recovers_the_truth_within_the_noise():
    sys.path.insert(0, str(ROOT / "python" / "examples"))
    from identify_leaf_spring import identify

    ddm = identify("leaf-spring-coarse", "ddm")
    assert ddm["success"], ddm["message"]
    off = np.abs(ddm["found"] - ddm["truth"]) / ddm["standard_error"]
    # within three standard errors of the estimate the noise leaves (0.09, 0.33, 0.36 seen)
    assert (off < 3.0).all(), (ddm["found"], ddm["standard_error"])
    fd = identify("leaf-spring-coarse", "fd")
    assert fd["success"], fd["message"]
    assert (np.abs(fd["found"] - fd["truth"]) < 3.0 * fd["standard_error"]).all()
    # the DDM Jacobian comes with the value: one analysis per iterate
    assert ddm["analyses"] == ddm["iterations"]
