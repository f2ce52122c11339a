"""A client of the polbrdf service (docs/service.md): submit specs, wait for
their jobs with progress, fetch the tables through the render-node cache.

>>> c = polbrdf.Client("http://farm:8080", token=os.environ.get("POLBRDF_TOKEN"))
>>> job = c.submit(spec)                    # POST /v1/brdfs
>>> c.wait(job["id"], progress=print)       # polls GET /v1/brdfs/ID
>>> table = c.table(job["id"])              # GET /v1/brdfs/ID/table, cached
"""

from __future__ import annotations

import json
import os
import time
import urllib.error
import urllib.request
from typing import Any, Callable, Mapping, Optional, Union

from ._native import FetchError, PolbrdfError, QueryError, SpecError


def _problem_error(status: int, body: bytes, what: str) -> PolbrdfError:
    """The exception of an RFC 9457 problem answer (docs/service.md, Errors)."""
    try:
        problem = json.loads(body.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        problem = {}
    detail = problem.get("detail") or body.decode("utf-8", "replace").strip() or f"HTTP {status}"
    kind = str(problem.get("type", ""))
    message = f"{what}: HTTP {status}: {detail}"
    if kind.endswith("/invalid-spec") or kind.endswith("/limit-exceeded"):
        err = SpecError(message)
        err.path = problem.get("path", "$")
        err.message = detail
        return err
    if kind.endswith("invalid-query"):
        return QueryError(message)
    return PolbrdfError(message)


class Client:
    """The polbrdf service at ``url`` (``http://host:8080``), with its bearer
    ``token`` (``POLBRDF_TOKEN``) when it needs one."""

    def __init__(self, url: str, token: Optional[str] = None, timeout_s: float = 30.0):
        self.url = url.rstrip("/")
        self.token = token
        self.timeout_s = timeout_s

    def __repr__(self) -> str:
        return f"polbrdf.Client({self.url!r})"

    def _request(self, method: str, path: str, body: Optional[bytes] = None) -> Any:
        req = urllib.request.Request(self.url + path, data=body, method=method)
        req.add_header("Accept", "application/json")
        if body is not None:
            req.add_header("Content-Type", "application/json")
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(req, timeout=self.timeout_s) as r:
                return json.loads(r.read().decode("utf-8"))
        except urllib.error.HTTPError as e:
            raise _problem_error(e.code, e.read(), f"{method} {path}") from None
        except urllib.error.URLError as e:
            raise FetchError(f"{method} {self.url}{path}: {e.reason}") from None

    def submit(self, spec: Union[Mapping[str, Any], str]) -> dict:
        """``POST /v1/brdfs``: the job's resource (``id``, ``status``,
        ``links``, ``covered_by``); a cached result answers at once with
        ``status`` ``done``. A refused spec raises :class:`SpecError` with
        the field's ``path``."""
        text = spec if isinstance(spec, str) else json.dumps(spec)
        return self._request("POST", "/v1/brdfs", text.encode("utf-8"))

    def status(self, id: str) -> dict:
        """``GET /v1/brdfs/ID``: the resource (``status``, ``progress`` in
        [0, 1], ``error_estimate``, ``error`` of a failed job)."""
        return self._request("GET", f"/v1/brdfs/{_id(id)}")

    def wait(
        self,
        id: Union[str, Mapping[str, Any]],
        timeout_s: Optional[float] = None,
        progress: Optional[Callable[[float, dict], None]] = None,
        poll_s: float = 0.25,
    ) -> dict:
        """Poll until the job is done and return its resource. ``progress``
        is called with ``(fraction, resource)`` whenever the fraction
        changes. A failed job raises (:class:`SpecError` for a spec the solve
        refused, else :class:`PolbrdfError`); ``timeout_s`` raises
        :class:`TimeoutError`."""
        key = _id(id)
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        last = None
        while True:
            r = self.status(key)
            frac = float(r.get("progress") or 0.0)
            if progress is not None and frac != last:
                progress(frac, r)
                last = frac
            if r["status"] == "done":
                return r
            if r["status"] == "failed":
                err = r.get("error") or {}
                raise _problem_error(
                    int(err.get("status", 422)),
                    json.dumps(err).encode("utf-8"),
                    f"job {key} failed",
                )
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"job {key} is still {r['status']} after {timeout_s} s")
            time.sleep(poll_s)

    def table(
        self,
        id: Union[str, Mapping[str, Any]],
        cache_dir: Union[str, os.PathLike, None] = None,
        revalidate: bool = False,
    ):
        """The result's table (:class:`polbrdf.Table`), through the
        render-node cache in ``cache_dir`` (default ``POLBRDF_CACHE_DIR``):
        downloaded once per machine, verified by its digest."""
        from . import Table

        return Table.load(
            f"{self.url}/v1/brdfs/{_id(id)}",
            cache_dir=cache_dir,
            token=self.token,
            revalidate=revalidate,
        )

    def solve(
        self,
        spec: Union[Mapping[str, Any], str],
        timeout_s: Optional[float] = None,
        progress: Optional[Callable[[float, dict], None]] = None,
        cache_dir: Union[str, os.PathLike, None] = None,
    ):
        """Submit, wait and fetch: the table of ``spec`` solved by the service."""
        job = self.submit(spec)
        self.wait(job["id"], timeout_s=timeout_s, progress=progress)
        return self.table(job["id"], cache_dir=cache_dir)


def _id(id: Union[str, Mapping[str, Any]]) -> str:
    return id["id"] if isinstance(id, Mapping) else str(id)
