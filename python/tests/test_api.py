"""`import polbrdf` against the command line it wraps and against physics
that does not come from this repository (docs/python.md)."""

import copy
import json
import math
import pickle
import threading
import time

import numpy as np
import pytest

import polbrdf
from conftest import PAINT, cli_eval, cli_json, random_pairs


def test_mie_is_the_command_line_and_rayleigh_in_the_small_limit():
    got = polbrdf.mie(n=1.5, k=0.0, wavelength_nm=550, radius_um=0.005)
    want = cli_json("mie", "--n", "1.5", "--k", "0", "--wavelength-nm", "550", "--radius-um", "0.005")
    assert got == want
    # Rayleigh (van de Hulst 1957, ch. 6): Q_sca = 8/3 x^4 |(m^2-1)/(m^2+2)|^2.
    x = 2 * math.pi * 0.005e3 / 550
    q = 8 / 3 * x**4 * ((1.5**2 - 1) / (1.5**2 + 2)) ** 2
    # Next order: a relative 6/5 x^2 (m^2-2)/(m^2+2) = 2.3e-4 here.
    assert abs(got["qsca"] - q) <= 1e-3 * q


def test_mie_lists_and_spec_dicts():
    got = polbrdf.mie(material="TiO2", wavelength_nm=550, radius_um=0.2, angles_deg=[0, 90, 180])
    want = cli_json(
        "mie", "--material", "TiO2", "--wavelength-nm", "550", "--radius-um", "0.2", "--angles-deg", "0,90,180"
    )
    assert got == want
    report = polbrdf.mie(spec=PAINT)
    assert json.dumps(report)  # a plain JSON document


def test_mie_bad_flag_is_an_error_naming_it():
    with pytest.raises(polbrdf.PolbrdfError, match="radius"):
        polbrdf.mie(material="TiO2", wavelength_nm=550, radius_um=-1)


def test_spec_errors_carry_the_field_path():
    bad = copy.deepcopy(PAINT)
    bad["layers"][0]["optical_thickness"] = -1
    with pytest.raises(polbrdf.SpecError) as e:
        polbrdf.solve(bad)
    assert e.value.path == "layers[0].optical_thickness"
    assert "outside" in e.value.message
    bad = copy.deepcopy(PAINT)
    bad["layers"][0]["scatterer"]["mie"]["radius_um"] = "big"
    with pytest.raises(polbrdf.SpecError) as e:
        polbrdf.solve(bad, points=[[10, 0, 20, 180]])
    assert e.value.path.startswith("layers[0].scatterer.mie.radius_um")
    assert isinstance(e.value, polbrdf.PolbrdfError)


def test_solve_points_is_the_command_line(workdir):
    rng = np.random.default_rng(7)
    pts = random_pairs(rng, 6)
    got = polbrdf.solve(PAINT, points=pts)
    assert got["mueller"].shape == (3, 6, 4, 4)
    assert got["wavelengths_nm"] == [450, 550, 650]
    spec_path = workdir / "paint_points.json"
    spec_path.write_text(json.dumps(PAINT))
    points_path = workdir / "points.json"
    points_path.write_text(
        json.dumps(
            {"points": [dict(zip(["theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"], map(float, p))) for p in pts]}
        )
    )
    doc = cli_json("solve", spec_path, "--points", points_path)
    for w, r in enumerate(doc["results"]):
        want = np.array([p["mueller"] for p in r["points"]])
        assert np.array_equal(got["mueller"][w], want)
    assert np.isnan(got["specular"]).all()


def test_table_eval_is_polbrdf_eval(paint_files):
    _, table_path = paint_files
    table = polbrdf.Table.load(table_path)
    assert list(table.wavelengths_nm) == [450.0, 550.0, 650.0]
    assert table.shape == (4, 4) and not table.has_specular
    rng = np.random.default_rng(3)
    pairs = random_pairs(rng, 12)
    for wl in (450.0, 523.0):
        want, _ = cli_eval(table_path, pairs, wl)
        wi = polbrdf.direction(pairs[:, 0], pairs[:, 1])
        wo = polbrdf.direction(pairs[:, 2], pairs[:, 3])
        got = table.eval(wi, wo, wl)
        scale = np.abs(want[:, 0, 0]).max()
        assert np.abs(got - want).max() <= 1e-12 * scale
        by_angles = table.eval_angles(pairs[:, 0], pairs[:, 1], pairs[:, 2], pairs[:, 3], wl)
        assert np.abs(by_angles - want).max() <= 1e-12 * scale


def test_table_from_solve_matches_the_direct_solve_to_its_stated_error():
    table = polbrdf.solve(PAINT)
    meta = table.metadata
    rng = np.random.default_rng(11)
    pts = random_pairs(rng, 20, max_theta_deg=80)
    direct = polbrdf.solve(PAINT, points=pts)["mueller"]
    for w, wl in enumerate([450, 550, 650]):
        got = table.eval_angles(pts[:, 0], pts[:, 1], pts[:, 2], pts[:, 3], wl)
        scale = np.abs(direct[w, :, 0, 0]).max()
        stated = meta["wavelengths"][w]["interpolation_error"]
        assert stated is not None and stated > 0
        # The table's stated interpolation error is relative to max f11.
        assert np.abs(got - direct[w]).max() <= 2 * stated * scale + 1e-12


def test_broadcasting_and_shapes(paint_files):
    table = polbrdf.Table.load(paint_files[1])
    wi = polbrdf.direction(np.linspace(0, 80, 5)[:, None], 0.0)  # (5, 1, 3)
    wo = polbrdf.direction(30.0, np.linspace(0, 350, 7))[None, :, :]  # (1, 7, 3)
    m = table.eval(wi, wo, 550.0)
    assert m.shape == (5, 7, 4, 4)
    one = table.eval(wi[2, 0], wo[0, 3], 550.0)
    assert one.shape == (4, 4) and np.array_equal(one, m[2, 3])
    per_wl = table.eval(wi[0, 0], wo[0, 0], np.array([450.0, 550.0, 650.0]))
    assert per_wl.shape == (3, 4, 4)
    # Not normalised directions are directions all the same.
    assert np.allclose(table.eval(3 * wi, wo, 550.0), m, rtol=1e-12, atol=0)


def test_query_errors_and_clamping(paint_files):
    table = polbrdf.Table.load(paint_files[1])
    wi = polbrdf.direction(20.0, 0.0)
    wo = polbrdf.direction(40.0, 170.0)
    with pytest.raises(polbrdf.QueryError, match="outside the table's range"):
        table.eval(wi, wo, 700.0)
    with pytest.raises(polbrdf.QueryError, match="give one"):
        table.eval(wi, wo)
    with pytest.raises(polbrdf.QueryError, match="into the surface"):
        table.eval(wi, -wo, 550.0)
    assert np.array_equal(table.eval(wi, wo, 700.0, clamp_wavelength=True), table.eval(wi, wo, 650.0))
    with pytest.raises(polbrdf.QueryError):
        table.eval(np.zeros((2, 2)), wo, 550.0)


def test_specular_of_a_mirror_base_is_polbrdf_eval(silver_files):
    table = polbrdf.Table.load(silver_files[1])
    assert table.has_specular
    pairs = np.array([[35.0, 20.0, 35.0, 200.0], [0.0, 0.0, 0.0, 180.0], [70.0, -100.0, 70.0, 80.0]])
    _, spec = cli_eval(silver_files[1], pairs, 550.0)
    got = table.specular(polbrdf.direction(pairs[:, 0], pairs[:, 1]), 550.0)
    assert got.shape == (3, 4, 4)
    assert np.abs(got - np.array(spec)).max() <= 1e-12
    assert table.specular(polbrdf.direction(10.0, 0.0), 450.0).shape == (4, 4)
    # Over a black base there is no specular term.
    assert polbrdf.solve({**PAINT, "base": "black"}).specular(polbrdf.direction(10.0, 0.0), 450.0) is None


def test_save_bytes_pickle_round_trip(paint_files, tmp_path):
    table = polbrdf.Table.load(paint_files[1])
    wi = polbrdf.direction(25.0, 10.0)
    wo = polbrdf.direction(55.0, 250.0)
    want = table.eval(wi, wo, 600.0)
    path = tmp_path / "copy.pbrdf"
    table.save(path)
    for t in (polbrdf.Table.load(path), polbrdf.Table.from_bytes(table.to_bytes()), pickle.loads(pickle.dumps(table))):
        assert np.array_equal(t.eval(wi, wo, 600.0), want)
    with pytest.raises(polbrdf.FetchError):
        polbrdf.Table.from_bytes(b"not a table")
    with pytest.raises(polbrdf.FetchError):
        polbrdf.Table.load(tmp_path / "missing.pbrdf")


def test_the_gil_is_released_while_solving():
    spec = copy.deepcopy(PAINT)
    spec["solver"]["streams"] = 32
    spec["needs"]["grid"]["polar_nodes"] = 64
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    start = time.perf_counter()
    try:
        polbrdf.solve(spec)
    finally:
        done.set()
        t.join()
    elapsed = time.perf_counter() - start
    during = [x for x in ticks if start < x < start + elapsed]
    # With the GIL held the counter could not run at all during the solve.
    assert elapsed > 0.05, f"the solve took only {elapsed:.3f} s: make it longer"
    assert len(during) >= 0.25 * elapsed / 0.0012, (len(during), elapsed)


def test_albedo_of_a_lambertian_base_alone():
    # Optical thickness 0 over a Lambertian base of albedo 0.3: f = 0.3/pi.
    spec = copy.deepcopy(PAINT)
    spec["layers"][0]["optical_thickness"] = 0.0
    table = polbrdf.solve(spec)
    a = table.albedo(polbrdf.direction([0.0, 60.0], 0.0), 550.0)
    assert np.allclose(a, 0.3, rtol=1e-6)
