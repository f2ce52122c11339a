"""`polbrdf.Client` against the real service (`polbrdf serve`, embedded
SQLite) started by the test."""

import copy

import numpy as np
import pytest

import polbrdf
from conftest import PAINT, TOKEN

def test_submit_wait_and_fetch_through_the_cache(service, tmp_path):
    client = polbrdf.Client(service, token=TOKEN)
    spec = copy.deepcopy(PAINT)
    spec["wavelengths_nm"] = [500, 600]
    job = client.submit(spec)
    assert job["status"] in ("queued", "running", "done")
    seen = []
    done = client.wait(job, timeout_s=120, progress=lambda f, r: seen.append(f))
    assert done["status"] == "done"
    assert seen[-1] == 1.0 and seen == sorted(seen)
    cache = tmp_path / "cache"
    first = client.table(job["id"], cache_dir=cache)
    again = client.table(job["id"], cache_dir=cache)
    assert (first.outcome, again.outcome) == ("miss", "hit")
    assert list(first.wavelengths_nm) == [500.0, 600.0]
    # The service's own answer at a pair is what the fetched table gives.
    wi = polbrdf.direction(30.0, 10.0)
    wo = polbrdf.direction(47.5, 200.0)
    local = polbrdf.solve(spec).eval(wi, wo, 500.0)
    assert np.array_equal(first.eval(wi, wo, 500.0), local)
    # Without a cache directory: downloaded and verified.
    direct = polbrdf.Table.load(f"{service}/v1/brdfs/{job['id']}", token=TOKEN)
    assert direct.outcome is None and np.array_equal(direct.eval(wi, wo, 500.0), local)


def test_refusals_are_python_exceptions(service):
    client = polbrdf.Client(service, token=TOKEN)
    bad = copy.deepcopy(PAINT)
    bad["layers"][0]["optical_thickness"] = -1
    with pytest.raises(polbrdf.SpecError) as e:
        client.submit(bad)
    assert e.value.path == "layers[0].optical_thickness"
    with pytest.raises(polbrdf.PolbrdfError, match="401"):
        polbrdf.Client(service).submit(PAINT)
    with pytest.raises(polbrdf.PolbrdfError, match="404"):
        client.status("0" * 64)
    with pytest.raises(polbrdf.FetchError):
        polbrdf.Client("http://127.0.0.1:9").status("x")


def test_a_service_with_private_reads(private_service, tmp_path):
    client = polbrdf.Client(private_service, token=TOKEN)
    spec = copy.deepcopy(PAINT)
    spec["wavelengths_nm"] = [550]
    job = client.submit(spec)
    client.wait(job, timeout_s=120)
    table = client.table(job, cache_dir=tmp_path / "cache")
    assert table.outcome == "miss" and list(table.wavelengths_nm) == [550.0]
    url = f"{private_service}/v1/brdfs/{job['id']}"
    assert polbrdf.Table.load(url, token=TOKEN).wavelengths_nm.tolist() == [550.0]
    with pytest.raises(polbrdf.FetchError, match="401"):
        polbrdf.Table.load(url)
    with pytest.raises(polbrdf.PolbrdfError, match="401"):
        polbrdf.Client(private_service).status(job["id"])
