"""The log of judgements on unseen scenes: every ``repro.compare … --split fresh`` run, committed.

Tune on ``dev``; ``test`` is held out but seen (the report and the figures show it); a preset change is
judged once on ``fresh`` scenes, whose seeds are drawn at run time and never seen before. Each such run
appends one record to ``report/judgements.jsonl`` (commit, command, seeds, date, per-aperture verdict
rows) and rewrites its readable view ``report/judgements.md``, which states how many judgements have been
made so far: a change judged again and again on fresh scenes until it passes is visible there.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["DEFAULT_LOG", "append_judgement", "read_judgements", "render_judgements"]

#: The committed log (one JSON record per line); its Markdown view sits beside it (``.md``).
DEFAULT_LOG = Path("report") / "judgements.jsonl"


def read_judgements(path) -> list[dict]:
    """The records of a log (empty when it does not exist yet).

    Raises
    ------
    ValueError
        A line that is not a JSON object (naming the file and the line).
    """
    path = Path(path)
    if not path.is_file():
        return []
    out = []
    for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if line.strip():
            rec = json.loads(line)
            if not isinstance(rec, dict):
                raise ValueError(f"{path}:{i} is not a judgement record; allowed: one JSON object per line")
            out.append(rec)
    return out


def render_judgements(records: list[dict]) -> str:
    """Markdown view of the log: the count, then per judgement its date, commit, command, seeds and verdicts."""
    lines = ["# Judgements on unseen scenes", "",
             "Every `python -m repro.compare A B --procedural N --split fresh` run, appended by the tool "
             "(the record: `judgements.jsonl`). Tune on dev; judge a change once here.", "",
             f"**Fresh-split judgements so far: {len(records)}**", ""]
    for k, rec in enumerate(records, 1):
        lines += [f"## {k}. {rec['b']} against {rec['a']} ({rec['date_utc']})", "",
                  f"- commit `{rec.get('commit')}`", f"- command `{rec['command']}`",
                  f"- seeds {rec['seeds'][0]}..{rec['seeds'][1]} ({rec['n_scenes']} scenes, {rec['scene_size']})", "",
                  f"| f/N | metric | {rec['a']} | {rec['b']} | B − A [95 %] | verdict |",
                  "|---|---|---|---|---|---|"]
        for r in rec["verdicts"]:
            lines.append(f"| {r['aperture']:g} | {r['metric']} | {r['mean_a']:.3f} | {r['mean_b']:.3f} | "
                         f"{r['mean_diff']:+.3f} [{r['ci_low']:+.3f}, {r['ci_high']:+.3f}] | {r['verdict']} |")
        if rec.get("baselines"):
            lines += ["", "Constant baselines (mean over the same scenes): " + "; ".join(
                f"{name} f/{ap} {v:.3f}" for name, per in rec["baselines"].items() for ap, v in per.items())]
        lines.append("")
    return "\n".join(lines)


def append_judgement(record: dict, path=DEFAULT_LOG) -> int:
    """Append ``record`` to the log at ``path`` and rewrite its Markdown view (both atomically).

    Returns
    -------
    int
        The number of judgements in the log, this one included.
    """
    from defocus_cache import atomic_write_text

    path = Path(path)
    records = [*read_judgements(path), record]
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, "".join(json.dumps(r, sort_keys=True) + "\n" for r in records))
    atomic_write_text(path.with_suffix(".md"), render_judgements(records))
    return len(records)
