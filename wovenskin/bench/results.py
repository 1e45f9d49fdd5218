"""What every bench result shares: its JSON form (the dataclass's fields) and a figure table."""

from __future__ import annotations

from dataclasses import asdict

from rich.table import Table


class BenchResult:
    """Base of a benchmark's result dataclass: :meth:`to_dict` gives every field."""

    def to_dict(self) -> dict:
        return asdict(self)  # type: ignore[call-overload]  # subclasses are dataclasses


def figure_table(title: str) -> Table:
    """An empty Rich table titled ``title`` with a "figure" and a right-aligned "value" column."""
    table = Table(title=title)
    table.add_column("figure")
    table.add_column("value", justify="right")
    return table
