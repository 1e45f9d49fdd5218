"""``wovenskin adapt``: fine-tune a recogniser to one person on one skin, in minutes.

:func:`adapt_model` takes a few minutes of one person's labelled streams or guided
recordings and a base model (the shipped one by default) and

1. splits the trials of every stream into trained and held out (:class:`~.adapt_data.
   TrialSplit`, a quarter of every class held out by default);
2. scores the base model on the held-out trials with the whole live pipeline (the
   "before" figures);
3. cuts training windows from the trained trials only, and mixes in *rehearsal* windows
   of other people: recordings of new simulated people and skins on the same grid
   (:func:`~wovenskin.training.datasets.sim.generate_sim_dataset`), so that fine-tuning
   on one person does not forget how others touch;
4. fine-tunes from the base model's torch weights (:mod:`~.transfer`: a class the base
   does not know, a user's own gesture, gets a new output row; a grid the base was not
   made for keeps everything but the stem's projection) at a low learning rate;
5. chooses the execution settings (``min_probability``, ``keep_probability``) by
   cross-fitting on the held-out trials (:mod:`~.adapt_arbiter`), which also gives the
   adapted model's held-out figures (the "after" figures: no trial is scored by a setting
   chosen on it);
6. scores both models on other people's windows (what fine-tuning may have forgotten);
7. puts the model in ``out`` only when it is not worse than the base on the held-out
   trials (:func:`~.adapt_arbiter.merit`; a base that cannot read the person's grid or
   rate is replaced by doing nothing, merit 0); otherwise the report is written, the model
   is kept aside in ``out/rejected`` and :class:`AdaptRefused` is raised.

Every step reports to ``progress`` as an :class:`AdaptEvent`.  The figures are in the
:class:`~.adapt_report.AdaptReport` written as ``out/adapt.json``.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from wovenskin.errors import ConfigError, DataError, WovenskinError
from wovenskin.io import atomic_write_text, to_jsonable
from wovenskin.recognition.checkpoint_meta import read_meta, write_meta
from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.recognition.pipeline import arbiter_settings_for_model, load_stream
from wovenskin.recognition.shipped import resolve_model_dir
from wovenskin.recording.formats import LabelledStream
from wovenskin.signal.config import ConditioningConfig
from wovenskin.skin.layout import SkinLayout
from wovenskin.training.adapt_arbiter import choose_arbiter, merit, score_streams
from wovenskin.training.adapt_data import TrialSplit, trial_windows
from wovenskin.training.adapt_report import AdaptReport
from wovenskin.training.adapt_settings import AdaptSettings
from wovenskin.training.checkpoint import load_checkpoint, save_checkpoint
from wovenskin.training.config import TrainConfig
from wovenskin.training.datasets.sim import generate_sim_dataset
from wovenskin.training.history import TrainEvent
from wovenskin.training.scoring import evaluate
from wovenskin.training.train import train_model
from wovenskin.training.transfer import merged_classes, transferred_model
from wovenskin.training.window_settings import WindowSettings

WORK_DIR = ".adapt-work"
REJECTED_DIR = "rejected"
REPORT_FILE = "adapt.json"


class AdaptRefused(WovenskinError):
    """The adapted model scored worse than its base on the held-out trials: not installed.

    ``report`` holds what was measured (also written to ``out/adapt.json``)."""

    def __init__(self, message: str, report: AdaptReport) -> None:
        super().__init__(message)
        self.report = report


@dataclass(frozen=True)
class AdaptEvent:
    """Progress: ``stage`` (what runs), ``done`` of ``total`` steps, an optional note."""

    stage: str
    done: int
    total: int
    note: str = ""


Progress = Callable[[AdaptEvent], None]


def _layout_of(stream: LabelledStream, meta) -> SkinLayout:
    """The stream's grid, with its pitches from its metadata or else the model's."""
    _, rows, cols = np.asarray(stream.frames).shape
    layout = (stream.metadata or {}).get("layout") or {}
    row_pitch = layout.get("row_pitch_mm") or meta.row_pitch_mm or SkinLayout.row_pitch_mm
    col_pitch = layout.get("col_pitch_mm") or meta.col_pitch_mm or SkinLayout.col_pitch_mm
    return SkinLayout(int(rows), int(cols), float(row_pitch), float(col_pitch))


def _read_inputs(paths: Sequence[str | Path]) -> list[LabelledStream]:
    if not paths:
        raise ConfigError("give at least one labelled stream (.npz) or recording (.wsrec)")
    streams = [load_stream(path) for path in paths]
    shapes = {np.asarray(s.frames).shape[1:] for s in streams}
    rates = {round(float(s.sample_rate_hz), 6) for s in streams}
    if len(shapes) > 1 or len(rates) > 1:
        raise DataError("the recordings come from different grids or sample rates: adapt one skin")
    for path, stream in zip(paths, streams, strict=True):
        if len(stream.event_labels) == 0:
            raise DataError(f"{path} has no labelled trials to learn from")
    return streams


class _Stages:
    """Counts the steps of each stage and reports them as :class:`AdaptEvent`."""

    def __init__(self, progress: Progress | None) -> None:
        self.progress = progress or (lambda event: None)
        self.stage, self.done, self.total = "", 0, 0

    def start(self, stage: str, total: int) -> None:
        self.stage, self.done, self.total = stage, 0, total
        self.progress(AdaptEvent(stage, 0, total))

    def step(self, note: str = "") -> None:
        self.done += 1
        self.progress(AdaptEvent(self.stage, self.done, self.total, note))


@dataclass
class _Person:
    """The person's streams, how they are split, and what the model must learn."""

    paths: list[str]
    pairs: list[tuple[LabelledStream, TrialSplit]]
    layout: SkinLayout
    conditioning: ConditioningConfig
    classes: list[str]


def _person(paths, base_meta, settings: AdaptSettings) -> _Person:
    streams = _read_inputs(paths)
    layout = _layout_of(streams[0], base_meta)
    rate = float(streams[0].sample_rate_hz)
    conditioning = ConditioningConfig.from_dict(base_meta.conditioning)
    if not np.isclose(rate, conditioning.sample_rate_hz, rtol=1e-3):
        conditioning = replace(conditioning, sample_rate_hz=rate)
    labels = sorted({str(x) for s in streams for x in s.event_labels})
    splits = [
        TrialSplit.of(s, settings.held_out_fraction, settings.seed + i)
        for i, s in enumerate(streams)
    ]
    if not any(split.held_out.any() for split in splits):
        raise DataError(
            "too few trials to hold any out for scoring: record at least two trials of a "
            "gesture (the guided `wovenskin record` makes three of each)"
        )
    pairs = list(zip(streams, splits, strict=True))
    classes = merged_classes(base_meta.class_names, labels)
    return _Person([str(p) for p in paths], pairs, layout, conditioning, classes)


def _user_windows(person: _Person, settings: AdaptSettings, rng, stages: _Stages):
    """Training windows from every stream's trained trials, shared by trained time."""
    stages.start("cutting windows", len(person.pairs))
    trained_s = [max(1.0, split.summary()["trained_s"]) for _, split in person.pairs]
    xs, ys = [], []
    for (stream, split), seconds in zip(person.pairs, trained_s, strict=True):
        share = seconds / sum(trained_s)
        batch = trial_windows(
            stream, split, person.classes, person.conditioning, WindowSettings(),
            max(1, round(settings.user_windows * share)),
            round(settings.user_invalid_windows * share), rng,
        )  # fmt: skip
        xs.append(batch.windows.astype(np.float32))
        ys.append(batch.labels.astype(np.int64))
        stages.step()
    return np.concatenate(xs), np.concatenate(ys)


def _rehearsal(person: _Person, settings: AdaptSettings, work: Path, stages: _Stages):
    """Windows of simulated other people on the person's grid: ``(train_x, train_y)`` to
    mix into training and ``(others_x, others_y)`` of further people kept for scoring."""
    shape = (0, WindowSettings().window_frames, person.layout.rows, person.layout.cols)
    empty = (np.zeros(shape, dtype=np.float32), np.zeros(0, dtype=np.int64))
    if not settings.rehearsal_recordings:
        return empty, empty
    n_train = settings.rehearsal_recordings
    n_all = n_train + max(1, n_train // 4)
    stages.start("simulating other people", n_all)
    ds = generate_sim_dataset(
        work / "rehearsal", n_all, settings.rehearsal_windows,
        max(1, round(0.4 * settings.rehearsal_windows)), 60.0, seed=settings.seed + 7,
        workers=1, progress=lambda done, total: stages.step(), overwrite=True,
        conditioning=person.conditioning, layout=person.layout,
    )  # fmt: skip
    remap = np.array([person.classes.index(name) for name in ds.class_names], dtype=np.int64)
    x = np.asarray(ds.windows, dtype=np.float32)
    y = remap[np.asarray(ds.labels, dtype=np.int64)]
    kept = np.asarray(ds.recording) >= n_train  # further people: scored, never trained on
    return (x[~kept], y[~kept]), (x[kept], y[kept])


def adapt_model(
    paths: Sequence[str | Path],
    out: str | Path,
    base: str | Path | None = None,
    settings: AdaptSettings | None = None,
    progress: Progress | None = None,
) -> AdaptReport:
    """Adapt ``base`` (None: the shipped model) to the person in ``paths``; see the module doc."""
    started = time.monotonic()
    settings = settings or AdaptSettings()
    stages = _Stages(progress)
    out = Path(out)
    base_dir = resolve_model_dir(base)
    stages.start("reading", 1)
    base_model, base_meta = load_checkpoint(base_dir)
    person = _person(paths, base_meta, settings)
    trials = sum(len(stream.event_labels) for stream, _ in person.pairs)
    stages.step(f"{trials} trials, {len(person.classes)} classes")

    before = None
    layout, rate = person.layout, person.conditioning.sample_rate_hz
    base_recognizer = OnnxRecognizer(base_dir, threads=settings.threads)
    base_rules = arbiter_settings_for_model(base_recognizer)
    if (layout.rows, layout.cols) == (base_meta.rows, base_meta.cols) and np.isclose(
        rate, base_meta.sample_rate_hz, rtol=1e-3
    ):
        stages.start("scoring the base model", len(person.pairs))
        before = score_streams(base_recognizer, person.pairs, base_rules, stages.step)

    work = out / WORK_DIR
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    rng = np.random.default_rng([settings.seed, 4099])
    user_x, user_y = _user_windows(person, settings, rng, stages)
    (rehearsal_x, rehearsal_y), (others_x, others_y) = _rehearsal(person, settings, work, stages)

    start, transfer = transferred_model(
        base_model, base_meta.class_names, base_meta.model_name, dict(base_meta.hparams),
        person.classes, layout.rows, layout.cols, base_meta.window,
    )  # fmt: skip
    init_meta = base_meta.with_updates(
        class_names=tuple(person.classes), rows=layout.rows, cols=layout.cols,
        row_pitch_mm=layout.row_pitch_mm, col_pitch_mm=layout.col_pitch_mm,
        sample_rate_hz=rate, conditioning=person.conditioning.to_dict(), arbiter={}, metrics={},
    )  # fmt: skip
    save_checkpoint(work / "init", start, init_meta, export_onnx=False)
    learns_afresh = bool(transfer.new_classes or transfer.reinitialised)
    lr = settings.new_class_lr if learns_afresh else settings.lr
    trained = _fine_tune(
        np.concatenate([user_x, rehearsal_x]), np.concatenate([user_y, rehearsal_y]),
        person, base_meta, base_dir, replace(settings, lr=lr), work, rng, stages,
    )  # fmt: skip

    recognizer = OnnxRecognizer(work / "model", threads=settings.threads)
    stages.start("choosing execution settings", len(person.pairs))
    choice = choose_arbiter(recognizer, person.pairs, base_rules, stages.step)
    after = choice.held_out
    others = None
    if others_x.shape[0]:
        others = _other_people(base_model, base_meta, work / "model", others_x, others_y,
                               person.classes)  # fmt: skip

    # without a base figure (another grid or rate) the model must beat doing nothing
    better = merit(after) >= merit(before) if before is not None else merit(after) > 0.0
    report = AdaptReport(
        base=str(base_dir), out=str(out), inputs=person.paths, classes=person.classes,
        new_classes=list(transfer.new_classes), transfer=transfer.describe(),
        splits=[split.summary() for _, split in person.pairs], before=before, after=after,
        arbiter=to_jsonable(choice.settings.__dict__), candidates=choice.candidates,
        others=others, validation_accuracy=trained.validation.accuracy,
        user_windows=int(user_x.shape[0]), rehearsal_windows=int(rehearsal_x.shape[0]),
        accepted=better or settings.force, forced=settings.force and not better,
        seconds=0.0, settings=to_jsonable(settings.__dict__),
    )  # fmt: skip
    _install(work / "model", out, report, choice.settings, report.accepted, started)
    if not report.accepted:
        floor = "the base" if before is not None else "doing nothing"
        raise AdaptRefused(
            f"the adapted model scored worse than {floor} on the held-out trials "
            f"(merit {merit(after):.3f} < {0.0 if before is None else merit(before):.3f}); "
            f"it is kept in "
            f"{out / REJECTED_DIR}, not installed (--force installs it anyway)",
            report,
        )
    return report


def _fine_tune(windows, targets, person: _Person, base_meta, base_dir: Path,
               settings: AdaptSettings, work: Path, rng, stages: _Stages):  # fmt: skip
    """Train from ``work/init`` on ``windows`` (a tenth held for the epoch choice)."""
    order = rng.permutation(windows.shape[0])
    n_val = max(len(person.classes), round(0.1 * order.size))
    val_idx, train_idx = np.sort(order[:n_val]), np.sort(order[n_val:])
    layout = person.layout
    data_meta = {
        "kind": "adapt",
        "sample_rate_hz": person.conditioning.sample_rate_hz,
        "conditioning": person.conditioning.to_dict(),
        "rows": layout.rows,
        "cols": layout.cols,
        "row_pitch_mm": layout.row_pitch_mm,
        "col_pitch_mm": layout.col_pitch_mm,
        "base_model": str(base_dir),
        "inputs": person.paths,
        "windows": int(windows.shape[0]),
    }
    config = TrainConfig(
        model=base_meta.model_name, hparams=dict(base_meta.hparams), epochs=settings.epochs,
        batch_size=settings.batch_size, lr=settings.lr, seed=settings.seed,
        patience=settings.epochs, warmup_epochs=0.25, threads=settings.threads,
        init_from=str(work / "init"),
    )  # fmt: skip
    steps = int(np.ceil(train_idx.size / settings.batch_size))
    stages.start("fine-tuning", settings.epochs * steps)

    def on_train(event: TrainEvent) -> None:
        if event.kind == "batch":
            stages.step(f"epoch {event.epoch}, loss {event.loss:.3f}")

    return train_model(
        windows, targets, person.classes, train_idx, val_idx, work / "model", data_meta,
        config, on_train,
    )  # fmt: skip


def _other_people(base_model, base_meta, adapted: Path, x, y, classes) -> dict:
    """Window accuracy of the base and the adapted model on other people's windows."""
    before = None
    if (x.shape[2], x.shape[3]) == (base_meta.rows, base_meta.cols):
        base_y = np.array([base_meta.class_names.index(classes[c]) for c in y], dtype=np.int64)
        before = evaluate(base_model, x, base_y, list(base_meta.class_names)).accuracy
    model, _ = load_checkpoint(adapted)
    after = evaluate(model, x, y, classes).accuracy
    return {"windows": int(x.shape[0]), "accuracy_before": before, "accuracy_after": after}


MODEL_FILES = ("model.pt", "model.onnx", "meta.json", "history.json", "learning_curve.png")


def _install(
    trained: Path, out: Path, report: AdaptReport, arbiter, accepted: bool, started: float
) -> None:
    """Move the adapted checkpoint into ``out`` (or ``out/rejected``), with its chosen
    execution settings and the adaptation record in ``meta.json``, and write the report."""
    target = out if accepted else out / REJECTED_DIR
    target.mkdir(parents=True, exist_ok=True)
    meta = read_meta(trained)
    record = {
        "base": report.base,
        "inputs": report.inputs,
        "new_classes": report.new_classes,
        "held_out_f1_before": None if report.before is None else report.before.f1,
        "held_out_f1_after": report.after.f1,
        "held_out_false_per_min_after": report.after.false_per_min,
    }
    meta = meta.with_updates(
        arbiter=to_jsonable(arbiter.__dict__),
        training_data={**meta.training_data, "adaptation": record},
    )
    write_meta(trained, meta)
    for name in MODEL_FILES:
        if (trained / name).is_file():
            shutil.move(str(trained / name), str(target / name))
    report.seconds = time.monotonic() - started
    atomic_write_text(out / REPORT_FILE, json.dumps(to_jsonable(report.to_dict()), indent=1))
    shutil.rmtree(out / WORK_DIR, ignore_errors=True)
