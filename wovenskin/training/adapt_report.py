"""What ``wovenskin adapt`` measured: :class:`AdaptReport`, its JSON and its tables.

The report pairs the base model's and the adapted model's event scores on the same
held-out trials (event F1, false activations a minute, median latency from first contact,
recall per class), the execution settings chosen and every candidate tried, how the
adapted model does on other people's windows (what fine-tuning may have forgotten), and
whether the model was installed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rich.table import Table

from wovenskin.recognition.event_scoring import EventScores


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{1000 * seconds:.0f} ms"


@dataclass
class AdaptReport:
    """Everything one adapt run measured and decided (``out/adapt.json``)."""

    base: str
    out: str
    inputs: list[str]
    classes: list[str]
    new_classes: list[str]
    transfer: str
    splits: list[dict]
    before: EventScores | None
    after: EventScores
    arbiter: dict[str, Any]
    candidates: list[dict]
    others: dict | None
    validation_accuracy: float
    user_windows: int
    rehearsal_windows: int
    accepted: bool
    forced: bool
    seconds: float
    settings: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "base": self.base,
            "out": self.out,
            "inputs": self.inputs,
            "classes": self.classes,
            "new_classes": self.new_classes,
            "transfer": self.transfer,
            "splits": self.splits,
            "held_out_before": None if self.before is None else self.before.to_dict(),
            "held_out_after": self.after.to_dict(),
            "arbiter": self.arbiter,
            "arbiter_candidates": self.candidates,
            "other_people": self.others,
            "validation_accuracy": self.validation_accuracy,
            "user_windows": self.user_windows,
            "rehearsal_windows": self.rehearsal_windows,
            "accepted": self.accepted,
            "forced": self.forced,
            "seconds": self.seconds,
            "settings": self.settings,
        }

    def table(self) -> Table:
        """Before and after on the held-out trials, one row per figure."""
        table = Table(title="held-out trials: base model -> adapted model")
        table.add_column("figure")
        table.add_column("base", justify="right")
        table.add_column("adapted", justify="right")
        b, a = self.before, self.after

        def cell(scores: EventScores | None, text) -> str:
            return "-" if scores is None else text(scores)

        rows = [
            ("events (detected)", lambda s: f"{s.n_events} ({s.n_detected})"),
            ("event F1", lambda s: f"{s.f1:.3f}"),
            ("false activations / min", lambda s: f"{s.false_per_min:.2f}"),
            ("median latency from contact", lambda s: _ms(s.median_latency_s)),
        ]
        for name, text in rows:
            table.add_row(name, cell(b, text), cell(a, text))
        if self.others is not None:
            before = self.others.get("accuracy_before")
            table.add_row(
                f"other people: window accuracy ({self.others['windows']})",
                "-" if before is None else f"{100 * before:.1f} %",
                f"{100 * self.others['accuracy_after']:.1f} %",
            )
        return table

    def class_table(self) -> Table:
        """Recall per class on the held-out trials, base and adapted."""
        table = Table(title="held-out recall per class")
        table.add_column("class")
        table.add_column("trials", justify="right")
        table.add_column("base", justify="right")
        table.add_column("adapted", justify="right")
        for name in sorted(self.after.per_class):
            counts = self.after.per_class[name]
            theirs = None if self.before is None else self.before.per_class.get(name)
            table.add_row(
                name,
                str(counts.events),
                "-" if theirs is None else f"{theirs.detected}/{theirs.events}",
                f"{counts.detected}/{counts.events}",
            )
        return table

    def verdict(self) -> str:
        """One line: installed or refused, where, the chosen threshold and the time taken."""
        p = self.arbiter.get("min_probability")
        where = self.out if self.accepted else f"{self.out}/rejected"
        if self.accepted and self.forced:
            head = "installed although worse than the base (--force)"
        elif self.accepted:
            head = "installed"
        elif self.before is not None:
            head = "refused: worse than the base on the held-out trials"
        else:
            head = "refused: no better than doing nothing on the held-out trials"
        return f"{head}: {where} (min_probability {p}, {self.seconds:.0f} s)"
