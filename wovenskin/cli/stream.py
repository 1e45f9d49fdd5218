"""Commands that run the recogniser over a recording: replay and eval-stream."""

from __future__ import annotations

from pathlib import Path

import typer

from wovenskin.cli.app import (
    JSON_OUT,
    MIN_PROBABILITY,
    MODEL,
    READER,
    THREADS,
    app,
    console,
    err_console,
    pipeline_settings,
    user_errors,
    warn,
)
from wovenskin.errors import DataError

# The options both commands share (one definition each).  Unset (None), each falls through
# to the model's recommendation (its meta.json), then to the settings' default
# (PipelineSettings, ArbiterSettings): cli.app.pipeline_settings.
EVERY = typer.Option(
    None, min=1, max=30, help="Run the model on every K-th frame's window (default 1)."
)
DWELL_MS = typer.Option(
    None,
    min=0.0,
    max=5000.0,
    help="Dwell time before a gesture acts (default: the model's recommendation, else 100).",
)


@app.command()
@user_errors
def replay(
    stream: Path = typer.Argument(..., help="Labelled-stream .npz (or native .wsrec)."),
    model: Path = MODEL,
    every: int | None = EVERY,
    dwell_ms: float | None = DWELL_MS,
    min_probability: float | None = MIN_PROBABILITY,
    reader: str | None = READER,
    threads: int = THREADS,
    json_out: bool = typer.Option(False, "--json", help="Print only the command log (JSON lines)."),
) -> None:
    """Run calibration, conditioning, recogniser and arbiter on a stream; print the commands."""
    from wovenskin.recognition.commandlog import commands_table, format_command_log
    from wovenskin.recognition.pipeline import load_recognizer, load_stream, run_pipeline
    from wovenskin.recording.files import unknown_labels, unknown_labels_message

    labelled = load_stream(stream)
    recognizer = load_recognizer(model, threads=threads)
    known = recognizer.class_names  # a model's custom gestures count as known
    unknown = unknown_labels(labelled.event_labels, known)
    if unknown:  # replay only prints commands; eval-stream refuses to score such a stream
        warn(unknown_labels_message(str(stream), unknown, known))
    settings = pipeline_settings(recognizer, every, dwell_ms, min_probability, reader)
    result = run_pipeline(labelled, recognizer, settings, on_warning=warn)
    if json_out:
        print(format_command_log(result.commands), end="", flush=True)
    else:
        console.print(commands_table(result.commands))
    err_console.print(
        f"{len(result.commands)} command changes, {result.duration_s:.1f} s of stream in "
        f"{result.elapsed_s:.2f} s ({result.realtime_factor:.0f}x real time, "
        f"{result.windows_inferred} of {result.windows_predicted} windows classified)",
        highlight=False,
    )


@app.command("eval-stream")
@user_errors
def eval_stream(
    streams: list[Path] = typer.Argument(..., help="Labelled-stream .npz files with events."),
    model: Path = MODEL,
    every: int | None = EVERY,
    dwell_ms: float | None = DWELL_MS,
    min_probability: float | None = MIN_PROBABILITY,
    reader: str | None = READER,
    threads: int = THREADS,
    json_out: bool = JSON_OUT,
) -> None:
    """Score the pipeline's commands against labelled events: event F1, false activations."""
    import json
    from dataclasses import asdict

    from wovenskin.recognition.event_scoring import (
        aggregate,
        per_class_table,
        score_stream,
        scores_table,
    )
    from wovenskin.recognition.pipeline import load_recognizer, load_stream, run_pipeline
    from wovenskin.recording.files import unknown_labels, unknown_labels_message

    recognizer = load_recognizer(model, threads=threads)
    known = recognizer.class_names  # a model's custom gestures count as known
    for path in streams:  # every file checked before minutes of pipeline are spent
        unknown = unknown_labels(load_stream(path).event_labels, known)
        if unknown:  # no command could match them: scored, they would pass as misses
            raise DataError(f"{unknown_labels_message(str(path), unknown, known)}; not scored")
    settings = pipeline_settings(recognizer, every, dwell_ms, min_probability, reader)
    rows, details = [], []
    for path in streams:
        labelled = load_stream(path)
        if len(labelled.event_labels) == 0:
            warn(f"{path} has no labelled events")
        with err_console.status(f"running the pipeline on {path}..."):
            result = run_pipeline(labelled, recognizer, settings, on_warning=warn)
        scores = score_stream(result.commands, labelled, known=known)
        rows.append((path.name, scores))
        details.append(
            {"path": str(path), "realtime_factor": result.realtime_factor, **scores.to_dict()}
        )
    total = aggregate(s for _, s in rows)
    if json_out:
        document = {
            "model": str(recognizer.checkpoint_dir.resolve()),
            "settings": {"every": settings.every, **asdict(settings.arbiter)},
            "streams": details,
            "total": total.to_dict(),
        }
        print(json.dumps(document))
    else:
        console.print(scores_table(rows, total))
        console.print(per_class_table(total))
