"""Shared fixtures of the Python package's tests (docs/python.md).

The tests compare the package with the `polbrdf` binary of this repository
(`POLBRDF_BIN`, default `target/release/polbrdf`, which `cargo test
--release` builds; tests/python_package.rs runs this suite) and with the
real Mitsuba 3 from PyPI.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest


REPO = pathlib.Path(__file__).resolve().parents[2]

#: A TiO2 paint over a grey Lambertian base at three wavelengths: a diffuse
#: table with a polarized, wavelength-dependent lobe.
PAINT = {
    "layers": [
        {
            "optical_thickness": 1.0,
            "scatterer": {"mie": {"material": "TiO2", "radius_um": 0.2, "host_index": 1.0}},
        }
    ],
    "base": {"lambertian": {"albedo": 0.3}},
    "wavelengths_nm": [450, 550, 650],
    "solver": {"streams": 12, "polarized": True},
    "needs": {"grid": {"polar_nodes": 24}},
}

#: Hematite over silver: a mirror base (specular delta) at three wavelengths.
RUST_ON_SILVER = {
    "layers": [
        {
            "optical_thickness": 0.5,
            "scatterer": {
                "mie": {
                    "material": "iron oxide",
                    "radius_um": 0.2,
                    "host_index": 1.0,
                }
            },
        }
    ],
    "base": {"fresnel": {"material": "silver"}},
    "wavelengths_nm": [450, 550, 650],
    "solver": {"streams": 12, "polarized": True},
    "needs": {"grid": {"polar_nodes": 24}},
}


def binary() -> str:
    path = os.environ.get("POLBRDF_BIN") or str(REPO / "target" / "release" / "polbrdf")
    if not os.path.exists(path):
        pytest.fail(f"the polbrdf binary {path} is missing: cargo build --release, or set POLBRDF_BIN")
    return path


def cli(*args, input_text=None) -> str:
    """Run the binary; its stdout."""
    r = subprocess.run([binary(), *map(str, args)], capture_output=True, text=True, input=input_text)
    if r.returncode != 0:
        raise AssertionError(f"polbrdf {' '.join(map(str, args))} failed: {r.stderr}")
    return r.stdout


def cli_json(*args):
    return json.loads(cli(*args))


TOKEN = "python-client-test-token"


def _serve(data, *flags):
    """`polbrdf serve` (embedded SQLite in `data`, one worker, the token
    `TOKEN`) on a free port: the process and its URL."""
    proc = subprocess.Popen(
        [binary(), "serve", "--listen", "127.0.0.1:0", "--data-dir", str(data), "--workers", "1", *flags],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env={"POLBRDF_TOKEN": TOKEN, "PATH": "/usr/bin:/bin"},
    )
    line = proc.stdout.readline()
    if not line.startswith("listening on "):
        proc.kill()
        raise AssertionError(f"polbrdf serve did not start: {line!r}")
    return proc, line.split()[-1]


def _served(data, *flags):
    proc, url = _serve(data, *flags)
    try:
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=30)


@pytest.fixture(scope="session")
def service(tmp_path_factory):
    """The URL of a service whose writes need `TOKEN`."""
    yield from _served(tmp_path_factory.mktemp("service"))


@pytest.fixture(scope="session")
def private_service(tmp_path_factory):
    """The URL of a service whose reads need `TOKEN` too (`--token-reads`)."""
    yield from _served(tmp_path_factory.mktemp("private"), "--token-reads")


@pytest.fixture(scope="session")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("polbrdf")


def _table_file(workdir, name, spec):
    spec_path = workdir / f"{name}.json"
    spec_path.write_text(json.dumps(spec))
    table_path = workdir / f"{name}.pbrdf"
    if not table_path.exists():
        cli("solve", spec_path, "--table", table_path)
    return spec_path, table_path


@pytest.fixture(scope="session")
def paint_files(workdir):
    """(spec path, table path) of PAINT, the table built by `polbrdf solve --table`."""
    return _table_file(workdir, "paint", PAINT)


@pytest.fixture(scope="session")
def silver_files(workdir):
    return _table_file(workdir, "rust_on_silver", RUST_ON_SILVER)


def random_pairs(rng, n, max_theta_deg=89.0):
    """`n` direction pairs uniform in solid angle on the hemisphere below
    `max_theta_deg`, as (theta_i, phi_i, theta_o, phi_o) degrees."""
    cmin = np.cos(np.radians(max_theta_deg))
    mu = rng.uniform(cmin, 1.0, size=(n, 2))
    phi = rng.uniform(-180.0, 180.0, size=(n, 2))
    th = np.degrees(np.arccos(mu))
    return np.stack([th[:, 0], phi[:, 0], th[:, 1], phi[:, 1]], axis=1)


def cli_eval(table_path, pairs, wavelength_nm=None):
    """`polbrdf eval` at each pair: (n, 4, 4) diffuse and specular (NaN if none)."""
    out = []
    spec = []
    for t_i, p_i, t_o, p_o in pairs:
        args = ["eval", table_path]
        args += [f"--theta-i={float(t_i)!r}", f"--phi-i={float(p_i)!r}"]
        args += [f"--theta-o={float(t_o)!r}", f"--phi-o={float(p_o)!r}"]
        if wavelength_nm is not None:
            args.append(f"--wavelength-nm={float(wavelength_nm)!r}")
        doc = cli_json(*args)
        out.append(doc["mueller"])
        spec.append(doc.get("specular"))
    return np.array(out, dtype=float), spec
