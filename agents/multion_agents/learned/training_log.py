"""Training logs: a CSV row per update, TensorBoard scalars, and a learning-curve PNG."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

from multion.common.files import replacing

CURVE_METRICS = ("success", "progress", "spl", "ppl")


class TrainingLog:
    """Appends to ``progress.csv`` and ``eval.csv`` in ``out`` (resumed runs keep appending,
    after :meth:`rewind`) and mirrors every value to TensorBoard under ``out/tensorboard``."""

    def __init__(self, out: Path, tensorboard: bool = True) -> None:
        self.out = out
        out.mkdir(parents=True, exist_ok=True)
        self.writer = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter
            except ImportError:  # tensorboard is optional: CSV and PNG still work
                pass
            else:
                self.writer = SummaryWriter(str(out / "tensorboard"))

    def write(self, name: str, row: dict[str, Any]) -> None:
        """Append ``row`` to ``{name}.csv``. A key the header lacks (a column added since the
        file was begun, say by a resumed run) widens it: the file is rewritten whole with the
        new columns last, blank in earlier rows (:func:`multion.common.files.replacing`)."""
        path = self.out / f"{name}.csv"
        fresh = not path.exists() or path.stat().st_size == 0
        columns = list(row) if fresh else _header(path)
        added = [key for key in row if key not in columns]
        if added:
            _widen(path, columns + added)
            columns += added
        with path.open("a", newline="") as handle:
            writer = csv.DictWriter(handle, columns, extrasaction="ignore")
            if fresh:
                writer.writeheader()
            writer.writerow({k: _round(row.get(k, "")) for k in columns})
        if self.writer is not None:
            step = int(row["frames"])
            for key, value in row.items():
                if key != "frames" and isinstance(value, int | float) and math.isfinite(value):
                    self.writer.add_scalar(f"{name}/{key}", value, step)
            self.writer.flush()

    def rewind(self, update: int) -> None:
        """Drop the rows of ``progress.csv`` and ``eval.csv`` logged after ``update``: a run
        interrupted past its last checkpoint logged updates that its resumption makes again.
        Each file is replaced whole (:func:`multion.common.files.replacing`), so none is left
        half written."""
        for name in ("progress", "eval"):
            path = self.out / f"{name}.csv"
            if not path.exists():
                continue
            with path.open(newline="") as handle:
                reader = csv.reader(handle)
                header = next(reader, None)
                rows = list(reader)
            if header is None or "update" not in header:
                continue
            column = header.index("update")
            kept = [row for row in rows if not _float(row[column]) > update]
            if len(kept) == len(rows):
                continue
            with replacing(path) as temporary, temporary.open("w", newline="") as handle:
                writer = csv.writer(handle)
                writer.writerow(header)
                writer.writerows(kept)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def read_csv(path: Path) -> list[dict[str, float]]:
    if not path.exists():
        return []
    with path.open() as handle:
        return [{k: _float(v) for k, v in row.items()} for row in csv.DictReader(handle)]


def plot_learning_curve(out: Path, title: str, baseline: dict[str, float] | None = None) -> Path:
    """``learning_curve.png``: train Success (running mean) and val evaluations against frames,
    with optional horizontal baselines (e.g. Rand+OracleFound's val Success), and below them
    the train episodes' mean return."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    train = [
        r for r in read_csv(out / "progress.csv") if math.isfinite(r.get("train_success", math.nan))
    ]
    evals = read_csv(out / "eval.csv")
    figure, (axis, lower) = plt.subplots(
        2, 1, figsize=(7, 6), dpi=120, sharex=True, gridspec_kw={"height_ratios": [2, 1]}
    )
    if train:
        frames = [r["frames"] for r in train]
        axis.plot(
            frames,
            [100 * r["train_success"] for r in train],
            color="tab:blue",
            alpha=0.5,
            label="train Success (last 100 episodes)",
        )
    for metric, color in (("success", "tab:orange"), ("spl", "tab:green")):
        if evals:
            axis.plot(
                [r["frames"] for r in evals],
                [100 * r[metric] for r in evals],
                "o-",
                color=color,
                label=f"val {metric.upper() if metric != 'success' else 'Success'}",
            )
    for label, value in (baseline or {}).items():
        axis.axhline(100 * value, color="gray", linestyle="--", label=label)
    if train:
        lower.plot(frames, [r["train_return"] for r in train], color="tab:purple")
    lower.set_ylabel("train return\n(last 100 episodes)")
    lower.set_xlabel("frames")
    lower.grid(alpha=0.3)
    axis.set_ylabel("%")
    axis.set_ylim(0, 100)
    axis.set_title(title)
    axis.grid(alpha=0.3)
    axis.legend(loc="upper left", fontsize=8)
    figure.tight_layout()
    path = out / "learning_curve.png"
    figure.savefig(path)
    plt.close(figure)
    return path


def _header(path: Path) -> list[str]:
    with path.open(newline="") as handle:
        return next(csv.reader(handle), [])


def _widen(path: Path, columns: list[str]) -> None:
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    with replacing(path) as temporary, temporary.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows(rows)


def _round(value: Any) -> Any:
    return round(value, 6) if isinstance(value, float) else value


def _float(value: str) -> float:
    try:
        return float(value)
    except ValueError:
        return math.nan
