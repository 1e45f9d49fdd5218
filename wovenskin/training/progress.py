"""Training shown in the terminal (Rich): a bar per epoch and one line per finished epoch."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from wovenskin.training.history import TrainEvent


class TrainProgressDisplay:
    """Rich display of training: a bar per epoch (running loss), a line per finished epoch.

    Use as a context manager; call it with ``(event)`` or ``(label, event)`` (the label
    names the run, e.g. ``"bilstm / grouped"``, when several train one after another).
    """

    def __init__(self, console: Console) -> None:
        self.console = console
        self._progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("loss {task.fields[loss]:.4f}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=console,
            transient=True,
        )
        self._task: Any = None
        self._key: tuple[str, int] | None = None
        self._best: dict[str, tuple[float, float]] = {}

    def __enter__(self) -> TrainProgressDisplay:
        self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._progress.stop()

    def __call__(self, label_or_event: str | TrainEvent, event: TrainEvent | None = None) -> None:
        if event is None:
            label, event = "", label_or_event  # type: ignore[assignment]
        else:
            label = str(label_or_event)
        assert event is not None and not isinstance(event, str)
        key = (label, event.epoch)
        if key != self._key:
            if self._task is not None:
                self._progress.remove_task(self._task)
            prefix = f"{label}  " if label else ""
            self._task = self._progress.add_task(
                f"{prefix}epoch {event.epoch}/{event.epochs}", total=event.batches, loss=event.loss
            )
            self._key = key
        self._progress.update(self._task, completed=event.batch, loss=event.loss)
        if event.kind == "epoch" and event.record is not None:
            self._progress.console.print(self._epoch_line(label, event), highlight=False)

    def _epoch_line(self, label: str, event: TrainEvent) -> str:
        r = event.record
        assert r is not None
        best_acc, best_loss = self._best.get(label, (-1.0, float("inf")))
        improved = r.val_accuracy > best_acc or (
            r.val_accuracy == best_acc and r.val_loss < best_loss
        )
        if improved:
            self._best[label] = (r.val_accuracy, r.val_loss)
        prefix = f"{label}  " if label else ""
        return (
            f"{prefix}epoch {r.epoch:>3}/{event.epochs} loss {r.train_loss:.4f} "
            f"train {100 * r.train_accuracy:6.2f}% val {100 * r.val_accuracy:6.2f}% "
            f"F1 {r.val_macro_f1:.4f} val loss {r.val_loss:.4f} lr {r.lr:.1e} "
            f"{r.seconds:4.0f} s" + (" [green]best[/]" if improved else "")
        )
