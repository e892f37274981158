"""The REST side of graybox for Python: datasets from numpy arrays, jobs followed with their
progress, models and templates as files, with the standard library's HTTP and numpy only.

Every failed request raises the same `GrayboxError` as the gRPC client, with the REST error's
`code` ("invalid_argument", "unprocessable", "not_found", "conflict", …), `message`, `field`
(the bad input's name, e.g. "training.epochs", when the server names one) and HTTP `status`.
As with gRPC, the server validates: a bad request reaches it and comes back with its reason.
"""

from __future__ import annotations

import http.client
import json
import random
import sys
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Optional, Sequence, Union, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._shared import GrayboxError

PathLike = Union[str, Path]
# A JSON object as the service answers it.
Json = dict[str, Any]
FINAL = ("succeeded", "failed", "cancelled")
PAUSE_MIN, PAUSE_MAX = 0.2, 5.0  # seconds between `wait`'s attempts to follow a job again


def _rows(a: ArrayLike, what: str, width: Optional[int] = None) -> list[list[float]]:
    """A 2-D float array as lists of rows (1-D arrays are one column)."""
    v = np.asarray(a, dtype=np.float64)
    if v.ndim == 1:
        v = v[:, None]
    if v.ndim != 2:
        raise ValueError(f"{what} must be 1-D or 2-D, got shape {v.shape}")
    return cast(list[list[float]], v.tolist())


class RestClient:
    """graybox's REST API at `base` ("http://127.0.0.1:8080"; "127.0.0.1:8080" also works).
    `token`: the bearer token of a server started with `--api-token`; `timeout`: seconds per
    request (a job's progress stream waits longer between events). Usable as a context
    manager for symmetry with `Client`; it holds no connection between requests."""

    def __init__(self, base: str = "http://127.0.0.1:8080", token: Optional[str] = None,
                 timeout: float = 60.0):
        self.base = (base if "://" in base else f"http://{base}").rstrip("/")
        self.token = token
        self.timeout = timeout

    def __enter__(self) -> "RestClient":
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    # ---------- requests ----------

    def request(self, method: str, path: str, body: Any = None, raw: Optional[bytes] = None,
                content_type: str = "application/json", query: Optional[Json] = None,
                parse: bool = True, timeout: Optional[float] = None) -> Any:
        """One request: the JSON answer (bytes with `parse=False`, None for 204). `timeout`:
        seconds for this one (default: the client's)."""
        url = self.base + path
        q = {k: v for k, v in (query or {}).items() if v is not None}
        if q:
            url += "?" + urllib.parse.urlencode(q)
        data = raw if raw is not None else (None if body is None else json.dumps(body).encode())
        req = urllib.request.Request(url, data=data, method=method, headers=self._headers(
            content_type if data is not None else None))
        try:
            with urllib.request.urlopen(req, timeout=timeout or self.timeout) as r:
                answer, status = r.read(), r.status
        except (OSError, http.client.HTTPException) as e:
            raise self._failure(e) from None
        if not parse:
            return answer
        item = json.loads(answer) if answer else None
        if method == "POST" and isinstance(item, dict) and status in (200, 201) and (
                path in ("/v1/datasets", "/v1/models", "/v1/templates")):
            # An upload answers 201 when it stored the item, 200 when the same bytes were
            # stored before (the item as it was).
            item.setdefault("created", status == 201)
        return item

    def _failure(self, e: Exception) -> GrayboxError:
        """A failed urlopen as a GrayboxError: the REST error of an HTTP answer, else
        `unavailable` (refused or unresolved, and also a connection closed or timed out before
        the whole answer came: a restarting service does both)."""
        if isinstance(e, urllib.error.HTTPError):
            return _error(e.code, e.read())
        return GrayboxError("unavailable", f"cannot reach graybox at {self.base}: "
                            f"{getattr(e, 'reason', e)}")

    def _headers(self, content_type: Optional[str]) -> dict[str, str]:
        h = {"accept": "application/json"}
        if content_type:
            h["content-type"] = content_type
        if self.token:
            h["authorization"] = f"Bearer {self.token}"
        return h

    def _json(self, method: str, path: str, body: Any = None, **kwargs: Any) -> Json:
        """`request` for an answer that is a JSON object."""
        return cast(Json, self.request(method, path, body, **kwargs))

    def _pages(self, path: str, query: Optional[Json] = None) -> Iterator[Json]:
        """Every item of a paged list, page after page."""
        token = None
        while True:
            page = self.request("GET", path, query={**(query or {}), "page_size": 500,
                                                    "page_token": token})
            yield from page["items"]
            token = page.get("next_page_token")
            if not token:
                return

    # ---------- datasets ----------

    def upload_dataset(self, q: ArrayLike, qdot: ArrayLike, u: ArrayLike, q_next: ArrayLike,
                       qdot_next: ArrayLike, dt: float, name: Optional[str] = None) -> Json:
        """Transitions from arrays ([N, n] each, [N, m] for `u`; 1-D means one column). The
        answer carries `id`, `count`, `created` (false: the same data was stored before) and
        the data's `warnings` (read them: angles
        in degrees, a wrong Δt, … are warned of, not refused)."""
        doc = {"dt": dt, "q": _rows(q, "q"), "qdot": _rows(qdot, "qdot"), "u": _rows(u, "u"),
               "q_next": _rows(q_next, "q_next"), "qdot_next": _rows(qdot_next, "qdot_next")}
        return self._json("POST", "/v1/datasets", doc, query={"name": name})

    def upload_trajectories(self, trajectories: Sequence[Mapping[str, ArrayLike]], dt: float,
                            name: Optional[str] = None) -> Json:
        """Trajectories, each a dict of `q` and `qdot` [T+1, n] and `u` [T, m] (u_t moves x_t
        to x_t+1); their boundaries are kept (multi-step training, replays)."""
        doc = {"dt": dt, "trajectories": [
            {k: _rows(t[k], f"trajectories[{i}].{k}") for k in ("q", "qdot", "u")}
            for i, t in enumerate(trajectories)]}
        return self._json("POST", "/v1/datasets", doc, query={"name": name})

    def upload_dataset_file(self, path: PathLike, name: Optional[str] = None,
                            dt: Optional[float] = None) -> Json:
        """A dataset file as `graybox simulate` writes it (JSON, which carries its own `dt`),
        or CSV (a file ending in .csv; columns q0…, qdot0…, u0…, q_next0…, qdot_next0…, README
        "Dataset files"), which has no time step of its own: give it as `dt` (seconds), e.g.
        `upload_dataset_file("log.csv", dt=0.01)`. A JSON file's `dt`, when given, must agree
        with the file's."""
        path = Path(path)
        csv = path.suffix.lower() == ".csv"
        if csv and dt is None:
            raise GrayboxError("invalid_argument", f"{path.name} is CSV, which carries no time "
                               f"step: give it in seconds, upload_dataset_file({str(path)!r}, "
                               f"dt=0.01)", field="dt")
        return self._json("POST", "/v1/datasets", raw=path.read_bytes(),
                          content_type="text/csv" if csv else "application/json",
                          query={"name": name, "dt": dt})

    def dataset(self, dataset_id: str) -> Json:
        return self._json("GET", f"/v1/datasets/{dataset_id}")

    def datasets(self) -> list[Json]:
        return list(self._pages("/v1/datasets"))

    def trajectories(self, dataset_id: str) -> list[Json]:
        """The dataset's trajectories: `index`, `start` row and `length` each."""
        return list(self._pages(f"/v1/datasets/{dataset_id}/trajectories"))

    def delete_dataset(self, dataset_id: str) -> None:
        """Refused (`conflict`) while a queued or running job uses it."""
        self.request("DELETE", f"/v1/datasets/{dataset_id}")

    # ---------- jobs ----------

    def submit_job(self, dataset_id: str, model: Union[str, Json] = "MVF",
                   template: Union[None, str, Json] = None, name: Optional[str] = None,
                   validation_dataset_id: Optional[str] = None,
                   training: Optional[Json] = None, init: Optional[Json] = None,
                   periodic: Optional[Sequence[bool]] = None) -> Json:
        """A training job (README "Training details" lists `training`'s fields and defaults):
        `model` a paper name ("MVF", "W-B", …) or a spec, `template` a built-in's name, a
        stored template's id or a template document. Returns the queued job."""
        body = {"dataset_id": dataset_id, "model": model, "name": name,
                "validation_dataset_id": validation_dataset_id, "template": template,
                "training": training, "init": init,
                "periodic": list(periodic) if periodic is not None else None}
        return self._json("POST", "/v1/jobs", {k: v for k, v in body.items() if v is not None})

    def job(self, job_id: str) -> Json:
        return self._json("GET", f"/v1/jobs/{job_id}")

    def jobs(self, state: Optional[str] = None) -> list[Json]:
        """Every job, newest first (optionally only those in `state`)."""
        return list(self._pages("/v1/jobs", {"state": state}))

    def cancel(self, job_id: str) -> Json:
        return self._json("POST", f"/v1/jobs/{job_id}/cancel")

    def metrics(self, job_id: str) -> Json:
        """Per-epoch figures as arrays: `epoch`, `train_loss`, `val_loss`, `val_horizon_loss`
        (a multi-step job's; NaN where there is none), `seconds`."""
        items = self.request("GET", f"/v1/jobs/{job_id}/metrics")["items"]
        def col(k: str) -> NDArray[np.float64]:
            return np.array([np.nan if i.get(k) is None else i[k] for i in items],
                            dtype=np.float64)

        return {"epoch": np.array([i["epoch"] for i in items], dtype=np.int64),
                "train_loss": col("train_loss"), "val_loss": col("val_loss"),
                "val_horizon_loss": col("val_horizon_loss"), "seconds": col("seconds")}

    def wait(self, job_id: str, progress: Union[bool, Callable[[Json], None]] = False,
             timeout: Optional[float] = None) -> Json:
        """Follows the job's event stream until it ends and returns the finished job (any
        final state: check `state`). `progress`: True prints a line per epoch to stderr, a
        function is called with each epoch's figures (`epoch`, `train_loss`, `val_loss`, and a
        multi-step job's `val_horizon_loss`, its validation loss over windows of its horizon:
        the loss that picks the kept epoch and becomes `best_val_loss`).
        A stream that drops or ends early, and a service that cannot be reached or answers
        `unavailable` (restarting), are followed again after a pause growing from 0.2 s to
        5 s; other errors (`not_found`, `unauthorized`, …) raise. `timeout` seconds in all
        raise `deadline_exceeded`; without it the wait has no end."""
        report: Optional[Callable[[Json], None]] = (
            None if progress is True or progress is False else progress)
        end = None if timeout is None else time.monotonic() + timeout
        reported = 0  # a stream followed again replays the epochs from the first
        state, pause = "unknown", PAUSE_MIN
        while True:
            # No read may wait past the deadline: a silent stream would keep the caller for
            # the whole socket timeout. (The floor lets a last look at the deadline answer.)
            limit = self.timeout if end is None else min(self.timeout,
                                                         max(end - time.monotonic(), 0.1))
            try:
                job = self._json("GET", f"/v1/jobs/{job_id}", timeout=limit)
                state = job["state"]
                if progress is True and report is None:
                    report = _printer(job_id, (job.get("training") or {}).get("horizon", 1))
                if state in FINAL:
                    return job
                for kind, data in self._events(f"/v1/jobs/{job_id}/events", end, limit):
                    pause = PAUSE_MIN  # the service answers: a later drop is retried soon
                    if kind == "progress" and report and data["epoch"] > reported:
                        reported = data["epoch"]
                        report(data)
                    elif kind == "state":
                        state = data["state"]
                        if state in FINAL:
                            return cast(Json, data)
            except GrayboxError as e:
                if e.code != "unavailable" and e.status not in (502, 503):
                    raise
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                raise GrayboxError("deadline_exceeded",
                                   f"job {job_id} still {state} after {timeout} s")
            # The stream ended, dropped or fell silent, or the service is away: pause before
            # reading the job again, so that a stream closed at once is not a busy loop; the
            # jitter keeps the clients of a restarted service from coming back in step.
            nap = pause * random.uniform(0.5, 1.0)
            time.sleep(nap if left is None else min(nap, left))
            pause = min(2 * pause, PAUSE_MAX)

    def _events(self, path: str, end: Optional[float],
                limit: float) -> Iterator[tuple[str, Any]]:
        """Server-sent events as (event, parsed data) until the stream ends, drops, is silent
        for `limit` seconds or `end` passes."""
        req = urllib.request.Request(self.base + path, headers=self._headers(None))
        try:
            r = urllib.request.urlopen(req, timeout=limit)
        except (OSError, http.client.HTTPException) as e:
            raise self._failure(e) from None
        with r:
            kind = "message"
            data: list[str] = []
            try:
                for raw in r:
                    line = raw.decode().rstrip("\r\n")
                    if line.startswith("event:"):
                        kind = line[6:].strip()
                    elif line.startswith("data:"):
                        data.append(line[5:].strip())
                    elif not line and data:
                        yield kind, json.loads("".join(data))
                        kind, data = "message", []
                    if end is not None and time.monotonic() > end:
                        return
            except (OSError, http.client.HTTPException, ValueError):
                return  # dropped, timed out or garbled: the caller reads the job again

    # ---------- models ----------

    def model(self, model_id: str) -> Json:
        """A model (or the model of the job `model_id` names): spec, n, m, dt, metrics,
        physical parameters, identifiable combinations, coordinates."""
        return self._json("GET", f"/v1/models/{model_id}")

    def models(self) -> list[Json]:
        return list(self._pages("/v1/models"))

    def download_model(self, model_id: str, path: Optional[PathLike] = None) -> bytes:
        """The model file (.gbx): its bytes, also written to `path` when given."""
        data: bytes = self.request("GET", f"/v1/models/{model_id}/checkpoint", parse=False)
        if path is not None:
            Path(path).write_bytes(data)
        return data

    def upload_model(self, file: Union[PathLike, bytes], name: Optional[str] = None) -> Json:
        """A model file (a path or its bytes); the same bytes again return the stored model
        (`created` false)."""
        data = file if isinstance(file, bytes) else Path(file).read_bytes()
        return self._json("POST", "/v1/models", raw=data,
                          content_type="application/octet-stream", query={"name": name})

    def model_urdf(self, model_id: str) -> str:
        """A URDF model's identified robot as URDF text."""
        text: bytes = self.request("GET", f"/v1/models/{model_id}/urdf", parse=False)
        return text.decode()

    def delete_model(self, model_id: str) -> None:
        self.request("DELETE", f"/v1/models/{model_id}")

    def replay(self, model_id: str, dataset_id: str, index: int = 0) -> Json:
        """The model's open-loop prediction of a recorded trajectory from its first state
        under its inputs: `t` [T+1], and `recorded` / `predicted` dicts of `q`, `qdot`
        [T+1, n]."""
        r = self.request("GET", f"/v1/models/{model_id}/rollout",
                         query={"dataset_id": dataset_id, "index": index})
        def arrays(d: Json) -> dict[str, NDArray[np.float64]]:
            return {k: np.asarray(d[k], dtype=np.float64) for k in ("q", "qdot")}

        return {"t": np.asarray(r["t"], dtype=np.float64), "recorded": arrays(r["recorded"]),
                "predicted": arrays(r["predicted"])}

    def evaluate(self, model_id: str, dataset_id: str, horizons: Sequence[int]) -> list[Json]:
        """Open-loop error against horizon on a dataset's trajectories: one dict per horizon
        (`horizon`, `seconds`, `windows`, `position_median`, `position_mean`,
        `velocity_median`, `velocity_mean`, `diverged`)."""
        body = {"dataset_id": dataset_id, "horizons": list(horizons)}
        items: list[Json] = self._json("POST", f"/v1/models/{model_id}/evaluate", body)["items"]
        return items

    def energy(self, model_id: str, x: ArrayLike, u: ArrayLike) -> Json:
        """Energy and work at a batch of states x [B, nq + nv] under u [B, m]: `kinetic`,
        `potential`, `total`, `power` ([B]), `inertial`, `coriolis`, `gravity`, `applied`
        ([B, nv]; inertial + coriolis + gravity = applied) and `parts`, F's named parts
        (dicts of `name`, `damping`, `values` [B, nv]). 409 for a naive model."""
        body = {"x": [list(map(float, r)) for r in np.asarray(x, dtype=np.float64)],
                "u": [list(map(float, r)) for r in np.asarray(u, dtype=np.float64)]}
        return self._json("POST", f"/v1/models/{model_id}/energy", body)

    # ---------- templates ----------

    def upload_template(self, template: Union[PathLike, Json]) -> Json:
        """A URDF file (.urdf, .xml), a formula template file (.json), or a template document
        as a dict; the answer lists its coordinates, inputs and trainable `parameters`."""
        if isinstance(template, dict):
            return self._json("POST", "/v1/templates", template)
        path = Path(template)
        xml = path.suffix.lower() in (".urdf", ".xml")
        return self._json("POST", "/v1/templates", raw=path.read_bytes(),
                          content_type="application/xml" if xml else "application/json")

    def template(self, template_id: str) -> Json:
        return self._json("GET", f"/v1/templates/{template_id}")

    def templates(self) -> list[Json]:
        return list(self._pages("/v1/templates"))

    def delete_template(self, template_id: str) -> None:
        self.request("DELETE", f"/v1/templates/{template_id}")


def _error(status: int, body: bytes) -> GrayboxError:
    """The REST error body `{"error": {"code", "message", "field"}}` as a GrayboxError."""
    try:
        e = json.loads(body)["error"]
    except (ValueError, KeyError, TypeError):
        e = {"code": "http_error", "message": body.decode(errors="replace")[:500]}
    return GrayboxError(e.get("code", "http_error"), e.get("message", ""), field=e.get("field"),
                        status=status)


def _printer(job_id: str, horizon: int) -> Callable[[Json], None]:
    """A line per epoch; a multi-step job's windowed validation loss named by its steps."""
    def report(m: Json) -> None:
        val, windows = m.get("val_loss"), m.get("val_horizon_loss")
        print(f"{job_id}: epoch {m['epoch']}, train {m['train_loss']:.4e}"
              + (f", val {val:.4e}" if val is not None else "")
              + (f", val {horizon}-step {windows:.4e}" if windows is not None else ""),
              file=sys.stderr)
    return report
