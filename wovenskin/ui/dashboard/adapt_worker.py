"""The child process of the dashboard's adapt run (:mod:`.adapt_job` starts it).

``python -m wovenskin.ui.dashboard.adapt_worker REQUEST`` runs
:func:`~wovenskin.training.adapt.adapt_model` once.  ``REQUEST`` is one JSON object:
``{"paths": [...], "out": DIR, "base": DIR or null, "settings": {AdaptSettings fields}}``.
It prints one JSON object per line on stdout: ``{"event": "progress", "stage", "done",
"total", "note"}`` for every :class:`~wovenskin.training.adapt.AdaptEvent`, then exactly
one outcome: ``{"event": "done", "report", "verdict"}`` (the model is installed in
``out``), ``{"event": "refused", "report", "message"}`` (worse than the base: the model is
kept in ``out/rejected``) or ``{"event": "failed", "message"}`` (one line).  Anything else
it has to say goes to stderr.  It runs at a lower scheduling priority than the dashboard,
whose control loop must keep its rate.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
from typing import Any

from wovenskin.errors import WovenskinError
from wovenskin.io import to_jsonable
from wovenskin.training.adapt import AdaptEvent, AdaptRefused, adapt_model
from wovenskin.training.adapt_settings import AdaptSettings

NICENESS = 5  # below the dashboard: the live loop wins a contended CPU


def emit(message: dict[str, Any]) -> None:
    """One line of the protocol on stdout, flushed at once (a figure that is not finite is
    sent as null: the page's JSON has no NaN)."""
    sys.stdout.write(json.dumps(_finite(to_jsonable(message)), allow_nan=False) + "\n")
    sys.stdout.flush()


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float (NaN, infinity) replaced by None."""
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_finite(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def run(request: dict[str, Any]) -> dict[str, Any]:
    """Adapt as ``request`` says, printing progress; returns the outcome message."""

    def progress(event: AdaptEvent) -> None:
        emit({"event": "progress", "stage": event.stage, "done": event.done,
              "total": event.total, "note": event.note})  # fmt: skip

    try:
        settings = AdaptSettings(**dict(request.get("settings") or {}))
        paths = [str(p) for p in request["paths"]]
        report = adapt_model(paths, request["out"], request.get("base"), settings, progress)
    except AdaptRefused as refused:
        return {"event": "refused", "report": refused.report.to_dict(), "message": str(refused)}
    except (WovenskinError, KeyError, TypeError) as exc:
        return {"event": "failed", "message": " ".join(str(exc).split()) or type(exc).__name__}
    return {"event": "done", "report": report.to_dict(), "verdict": report.verdict()}


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        emit({"event": "failed", "message": "usage: adapt_worker REQUEST-JSON"})
        return 2
    with contextlib.suppress(OSError, AttributeError):  # not every system can renice
        os.nice(NICENESS)
    try:
        request = json.loads(args[0])
    except ValueError as exc:
        emit({"event": "failed", "message": f"the request is not JSON: {exc}"})
        return 2
    if not isinstance(request, dict):
        emit({"event": "failed", "message": "the request must be a JSON object"})
        return 2
    emit(run(request))
    return 0


if __name__ == "__main__":
    sys.exit(main())
