"""Tables of the global-localization / kidnapping experiment ([`mcl.experiments.recovery`][mcl.experiments.recovery]):
runs.csv, summary.csv and summary.md. Times in seconds of simulated time, errors in metres.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mcl.experiments.convergence import RecoveryStats
from racecar_sim.file_guard import writable

if TYPE_CHECKING:
    from mcl.experiments.recovery_config import RecoveryConfig, RecoveryRun

__all__ = ["summary_markdown", "write_tables"]


def _fmt(value: float, digits: int = 2) -> str:
    return "–" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def _pct(value: float) -> str:
    return "–" if not math.isfinite(value) else f"{100 * value:.0f} %"


def summary_markdown(config: RecoveryConfig, runs: Sequence[RecoveryRun]) -> str:
    """The summary table (one row) and the per-run table, as Markdown."""
    stats = [r.stats for r in runs if r.stats is not None]
    n_failed = sum(r.result.status == "failed" for r in runs)
    times = np.array([s.convergence_s for s in stats], dtype=np.float64)
    conv = times[np.isfinite(times)]
    ok = [s.success for s in stats]

    def mean_of(name: str) -> float:
        values = np.array([getattr(s, name) for s in stats], dtype=np.float64)
        values = values[np.isfinite(values)]
        return float(values.mean()) if values.size else math.nan

    walls = [r.result.wall_s for r in runs if r.result.status == "ok"]
    head = (
        f"| runs | success (≤ {config.limit:g} s) | median s | mean s | p90 s | max s | never | error "
        "after (m) | ambiguous | confidently wrong | wrong after limit | peak particles | final "
        "particles | wall s |"
    )
    row = [
        f"{len(stats)}" + (f" ({n_failed} failed)" if n_failed else ""),
        f"{sum(ok)}/{len(ok)} = {_pct(float(np.mean(ok)) if ok else math.nan)}",
        _fmt(float(np.median(conv)) if conv.size else math.nan),
        _fmt(float(conv.mean()) if conv.size else math.nan),
        _fmt(float(np.percentile(conv, 90)) if conv.size else math.nan),
        _fmt(float(conv.max()) if conv.size else math.nan),
        f"{int(np.count_nonzero(~np.isfinite(times)))}",
        _fmt(mean_of("error_after"), 3),
        _pct(mean_of("ambiguous_fraction")),
        _pct(mean_of("wrong_fraction")),
        _pct(mean_of("wrong_after_fraction")),
        _fmt(mean_of("peak_particles"), 0),
        _fmt(mean_of("final_particles"), 0),
        _fmt(float(np.mean(walls)) if walls else math.nan, 1),
    ]
    lines = [head, "|" + "---|" * len(row), "| " + " | ".join(row) + " |", ""]
    lines += [
        "| run | seed | lost at s | converged after s | success | error after (m) | ambiguous "
        "| confidently wrong | peak particles | status |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        s = r.stats
        if s is None:
            lines.append(
                f"| {r.result.spec.run_id} | {r.result.spec.seed} | – | – | – | – | – | – | – | "
                f"failed: {r.result.error} |"
            )
            continue
        lines.append(
            f"| {r.result.spec.run_id} | {r.result.spec.seed} | {s.lost_at:g} | "
            f"{_fmt(s.convergence_s)} | {'yes' if s.success else 'no'} | "
            f"{_fmt(s.error_after, 3)} | {_pct(s.ambiguous_fraction)} | "
            f"{_pct(s.wrong_fraction)} | {s.peak_particles} | {r.result.status} |"
        )
    return "\n".join(lines)


def write_tables(
    config: RecoveryConfig, runs: Sequence[RecoveryRun], out_dir: str | os.PathLike[str]
) -> list[Path]:
    """Write runs.csv and summary.md into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    runs_path, md_path = out / "runs.csv", out / "summary.md"
    fields = ["run_id", "seed", "status", *RecoveryStats.__dataclass_fields__, "wall_s", "error"]
    with writable(runs_path).open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fields)
        writer.writeheader()
        for r in runs:
            row: dict[str, Any] = {
                "run_id": r.result.spec.run_id,
                "seed": r.result.spec.seed,
                "status": r.result.status,
                "wall_s": round(r.result.wall_s, 3),
                "error": r.result.error,
            }
            if r.stats is not None:
                row.update(asdict(r.stats))
            writer.writerow(row)
    c = config
    f = c.localization.filter
    what = (
        "global localization (particles uniform over free space, car at a random start)"
        if c.scenario == "global"
        else f"kidnapping (tracking from the true start, car teleported at {c.kidnap_time:g} s)"
    )
    text = [
        f"# MCL {c.scenario} experiment",
        "",
        f"Map `{c.map}`, {what}; driver `{c.driver}`, seeds {c.first_seed}.."
        f"{c.first_seed + c.seeds - 1}, {c.total_duration:g} s of simulated time per run. "
        f"Converged = position error < {c.criteria.position_m:g} m and heading error < "
        f"{math.degrees(c.criteria.heading_rad):g} deg held for {c.criteria.hold_s:g} s; times "
        f"from the moment the filter lost the car; success = converged within {c.limit:g} s. "
        f"Confidently wrong = not flagged ambiguous while the position error exceeds "
        f"{c.criteria.wrong_m:g} m (fraction of the steps after losing the car; 'after limit': "
        f"of the steps from the time limit on). Filter: "
        f"KLD {f.kld.min_particles}-{f.kld.max_particles} particles, global start "
        f"{f.global_particles or f'{f.global_density:g}/m²'}, alpha_slow "
        f"{f.augmented.alpha_slow:g}, alpha_fast {f.augmented.alpha_fast:g}, squash "
        f"{c.localization.sensor.squash_exponent:g}, a scan every "
        f"{f.update_min_distance:g} m / {f.update_min_angle:g} rad.",
        "",
        summary_markdown(config, runs),
        "",
    ]
    writable(md_path).write_text("\n".join(text), encoding="utf-8")
    return [runs_path, md_path]
