"""The claims matrix: every claim judged per (method preset, scene set) on the rows of the results table.

A column is a (preset, scene set) found in the claim figures' rows: the ``paper`` preset first, the
hand-built scene sets first and the procedural test split (``procedural_test``) last. A cell reads only
its own rows (:func:`cell_rows`): the claim's figure, the cell's preset (and the preset-independent
rows, such as Fig. 7's renders and oracles) along the preset axis, the cell's scene set along the
scene-set axis; a claim that does not vary with an axis reads the ``paper`` preset / the rows without
a scene set there — except on the procedural test split, which is always its own evaluation of the
claims computed on it (:attr:`~experiments.claims.core.Claim.test_split`). A figure without rows for
the cell gives "not evaluated" (never another preset's or set's numbers).

Each verdict names its evaluation (``"<figure>/<preset>/<scene set>/<mode>-<config hash>"``, with
``all-presets`` / ``all-scene-sets`` along the axes the claim does not vary with); cells of one claim
share an evaluation only along those axes (:func:`evaluation_problems` checks it, :func:`cell_sources`
says which earlier cell a repeated one equals). :func:`fragile_claims` lists the claims whose verdict
on the test split differs from the one on a hand-built set.
"""

from __future__ import annotations

import dataclasses

from ..results_query import MissingData, Results
from .catalogue import CLAIMS
from .core import ALL_PRESETS, ALL_SCENE_SETS, DEFAULT_PRESET, VERDICTS, Claim, Verdict

__all__ = ["JUDGED", "cell_rows", "cell_sources", "claim_matrix", "claims_document", "columns", "evaluate_claims",
           "evaluation_id", "evaluation_problems", "fragile_claims", "is_self_check", "scope_note"]

#: Verdicts that judge the claim (the others say it could not be judged).
JUDGED = ("reproduced", "partly reproduced", "not reproduced")


def _test_split() -> str:
    from ..scene_sets import PROCEDURAL_TEST

    return PROCEDURAL_TEST


def _as_results(table) -> Results:
    return table if isinstance(table, Results) else Results(table)


def columns(table) -> list[tuple[str, str | None]]:
    """Every (preset, scene set) of the claim figures' rows: ``paper`` first, then the other presets in
    order; the hand-built sets (in :func:`experiments.scene_sets.scene_set_names` order; None when the rows
    name none) before the test split."""
    from ..scene_sets import scene_set_names

    rows = _as_results(table).where(figure=tuple({c.figure for c in CLAIMS}))
    presets = [DEFAULT_PRESET] + [p for p in rows.distinct("preset") if p and p != DEFAULT_PRESET]
    present = set(rows.distinct("scene_set"))
    test = _test_split()
    order = [s for s in scene_set_names() if s != test]
    hand = [s for s in order if s in present] + sorted(s for s in present if s and s not in order and s != test)
    sets = (hand or [None]) + ([test] if test in present else [])
    return [(p, s) for s in sets for p in presets]


def is_self_check(claim: Claim, scene_set: str | None, verdict: Verdict | None = None) -> bool:
    """Whether ``claim``'s cell on ``scene_set`` is a harness self-check (:attr:`Claim.self_check`), not
    held-out evidence: every cell of a claim whose scope is "everywhere", the test split's cells of one
    whose scope is "test_split"; never a cell whose ``verdict`` is "not evaluated" (no evidence at all)."""
    if not claim.self_check or (verdict is not None and verdict.verdict == "not evaluated"):
        return False
    return claim.self_check_scope == "everywhere" or scene_set == _test_split()


def cell_rows(table, claim: Claim, *, preset: str, scene_set: str | None):
    """The rows a cell of ``claim`` reads (:class:`~experiments.results_query.Results`), or a str: why none."""
    rows = _as_results(table).where(figure=claim.figure)
    if not rows:
        return f"no rows of {claim.figure} (python -m repro.figures {claim.figure} writes them)"
    if "preset" in claim.varies_with:
        if not rows.where(preset=preset):
            have = sorted(p for p in rows.distinct("preset") if p)
            return f"{claim.figure}: no rows of preset {preset!r} (has {have or 'none'})"
        rows = rows.where(preset=(preset, None))
    else:
        rows = rows.where(preset=(DEFAULT_PRESET, None))
    test = _test_split()
    if scene_set == test and not claim.test_split:
        return f"{claim.figure}: the claim is not computed on the procedural test split"
    if scene_set == test or ("scene_set" in claim.varies_with and scene_set is not None):
        got = rows.where(scene_set=scene_set)
        if not got:
            have = sorted(s for s in rows.distinct("scene_set") if s)
            return f"{claim.figure}: no rows of scene set {scene_set!r} (has {have or 'none'})"
        return got
    got = rows.where(scene_set=None)
    return got if got else f"{claim.figure}: no rows without a scene set"


def evaluation_id(claim: Claim, rows: Results, *, preset: str, scene_set: str | None) -> str:
    """``"<figure>/<preset>/<scene set>/<mode>-<config hash>"`` of a cell (``all-presets`` / ``all-scene-sets``
    along the axes the claim does not vary with; the test split is always named)."""
    p = preset if "preset" in claim.varies_with else ALL_PRESETS
    named = "scene_set" in claim.varies_with or scene_set == _test_split()
    s = (scene_set or "default") if named else ALL_SCENE_SETS
    runs = sorted({str(e).removeprefix(f"{claim.figure}-") for e in rows.distinct("evaluation_id")})
    return f"{claim.figure}/{p}/{s}/{'+'.join(runs) or 'unrecorded'}"


def _judge(claim: Claim, table, preset: str, scene_set) -> Verdict:
    rows = cell_rows(table, claim, preset=preset, scene_set=scene_set)
    if isinstance(rows, str):
        return Verdict("not evaluated", f"missing data: {rows}", {})
    try:
        verdict = claim.check(rows)
    except MissingData as exc:
        return Verdict("not evaluated", f"missing data: {exc}", {})
    except Exception as exc:  # noqa: BLE001 - a raising check is reported, not swallowed as missing
        verdict = Verdict("error", f"the check raised {type(exc).__name__}: {exc}", {})
    if verdict.verdict not in VERDICTS:
        verdict = Verdict("error", f"the check returned an unknown verdict {verdict.verdict!r}", {})
    return dataclasses.replace(verdict, evaluation=evaluation_id(claim, rows, preset=preset, scene_set=scene_set))


def evaluate_claims(table, *, preset: str = DEFAULT_PRESET, scene_set: str | None = None,
                    claims: tuple[Claim, ...] = CLAIMS) -> list[tuple[Claim, Verdict]]:
    """Every claim judged on one (preset, scene set) of the results table.

    Parameters
    ----------
    table : Results or iterable of dict
        Rows of the long results table (:mod:`experiments.results_table`).
    preset : str, keyword-only
    scene_set : str or None, keyword-only
        None: the rows without a scene set only.
    claims : tuple of Claim, keyword-only

    Returns
    -------
    list of (Claim, Verdict)
        In ``claims`` order. Missing rows or values give "not evaluated" with the reason; a check that
        raises anything else gives "error" with the exception (a harness failure, never hidden).
    """
    table = _as_results(table)
    return [(c, _judge(c, table, preset, scene_set)) for c in claims]


def claim_matrix(table) -> dict:
    """``{(preset, scene set): [(Claim, Verdict), ...]}`` for every column of :func:`columns`."""
    table = _as_results(table)
    by_figure = Results(table.where(figure=tuple({c.figure for c in CLAIMS})).rows)
    return {(p, s): evaluate_claims(by_figure, preset=p, scene_set=s) for p, s in columns(by_figure)}


def scope_note(claim: Claim, *, test_split: bool = False) -> str:
    """What the first cell of a claim stands for when the claim does not vary with every axis
    (``test_split``: a cell of the procedural test split, which is always its own scene set)."""
    v = frozenset((*claim.varies_with, "scene_set") if test_split else claim.varies_with)
    note = {frozenset(): "all presets and scene sets", frozenset({"preset"}): "all scene sets",
            frozenset({"scene_set"}): "all presets"}.get(v, "")
    if note and claim.test_split and "scene_set" not in v:
        note = note.replace("scene sets", "hand-built scene sets")
    return note


def cell_sources(matrix) -> dict:
    """``{(column, claim id): earlier column whose cell is the same evaluation, or None}``."""
    first: dict = {}
    out = {}
    for col, rows in matrix.items():
        for claim, v in rows:
            key = (claim.id, v.evaluation)
            if v.evaluation and key in first:
                out[(col, claim.id)] = first[key]
            else:
                first.setdefault(key, col)
                out[(col, claim.id)] = None
    return out


def claims_document(matrix) -> list[dict]:
    """The ``"matrix"`` of ``claims.json``: per column and claim the verdict, evidence, evaluation id, axes,
    ``self_check`` (why the cell is a harness self-check, or None: :func:`is_self_check`) and the column
    whose cell it repeats (``same_as``)."""
    sources = cell_sources(matrix)
    doc = []
    for (p, sset), rows in matrix.items():
        cells = {}
        for c, v in rows:
            src = sources[((p, sset), c.id)]
            cells[c.id] = {"verdict": v.verdict, "evidence": v.evidence, "evaluation": v.evaluation,
                           "varies_with": list(c.varies_with), "test_split": c.test_split,
                           "self_check": c.self_check if is_self_check(c, sset, v) else None,
                           "same_as": None if src is None else {"preset": src[0], "scene_set": src[1]}}
        doc.append({"preset": p, "scene_set": sset, "verdicts": cells})
    return doc


def _id_problems(claim: Claim, ev: str, p, sset) -> list[str]:
    parts = ev.split("/")
    where = f"{claim.id} at ({p}, {sset})"
    if len(parts) != 4 or parts[0] != claim.figure:
        return [f"{where}: evaluation {ev!r} is not '{claim.figure}/<preset>/<scene set>/<config>'"]
    out = []
    if "preset" in claim.varies_with and parts[1] != p:
        out.append(f"{where}: evaluation {ev!r} is not of preset {p!r}")
    if "preset" not in claim.varies_with and parts[1] != ALL_PRESETS:
        out.append(f"{where}: evaluation {ev!r} names a preset, the claim varies with none")
    named = "scene_set" in claim.varies_with or sset == _test_split()
    if named and sset is not None and parts[2] != sset:
        out.append(f"{where}: evaluation {ev!r} is not of scene set {sset!r}")
    if not named and parts[2] != ALL_SCENE_SETS:
        out.append(f"{where}: evaluation {ev!r} names a scene set, the claim varies with none")
    return out


def evaluation_problems(document: list[dict], claims: tuple[Claim, ...] = CLAIMS) -> list[str]:
    """Where a claims matrix breaks "one evaluation per cell" (empty: it holds).

    One line per problem: a judged cell without an evaluation id; an id that does not name the cell's
    preset / scene set along an axis the claim varies with (or the test split); two cells of a claim
    sharing an id although they differ along such an axis; a claim that varies with nothing evaluated
    more than once on the hand-built sets.
    """
    by_id = {c.id: c for c in claims}
    problems, seen, ids_of = [], {}, {}
    for entry in document:
        p, sset = entry["preset"], entry["scene_set"]
        for cid, cell in entry["verdicts"].items():
            claim = by_id.get(cid)
            if claim is None:
                problems.append(f"{cid}: not a claim")
                continue
            ev = cell.get("evaluation") or ""
            if not ev:
                if cell.get("verdict") != "not evaluated":
                    problems.append(f"{cid} at ({p}, {sset}): verdict {cell.get('verdict')!r} names no evaluation")
                continue
            bad = _id_problems(claim, ev, p, sset)
            problems += bad
            if len(ev.split("/")) != 4:
                continue
            if sset != _test_split():
                ids_of.setdefault(cid, set()).add(ev)
            first = seen.setdefault((cid, ev), (p, sset))
            if first != (p, sset):
                differ = [a for a, x, y in (("preset", first[0], p), ("scene_set", first[1], sset)) if x != y]
                along = [a for a in differ if a in claim.varies_with]
                if along:
                    problems.append(f"{cid}: cells {first} and {(p, sset)} share evaluation {ev!r} but the claim "
                                    f"varies with {', '.join(along)}")
    for cid, ids in ids_of.items():
        if not by_id[cid].varies_with and len(ids) > 1:
            problems.append(f"{cid}: varies with nothing but has {len(ids)} evaluations {sorted(ids)}")
    return problems


def fragile_claims(matrix) -> list[dict]:
    """Claims whose verdict on the procedural test split differs from their verdict on a hand-built set.

    Returns
    -------
    list of dict
        Per claim and preset: ``claim`` (id), ``preset``, ``test`` (``verdict``, ``evidence``,
        ``evaluation`` on the test split) and ``hand_built`` (the same per hand-built scene set, one
        entry per distinct evaluation). Only judged verdicts (not "not evaluated" / "error") count, and
        no harness self-check (:func:`is_self_check`): it says nothing about unseen scenes.
    """
    test = _test_split()
    out = []
    for claim in CLAIMS:
        if not claim.test_split or is_self_check(claim, test):
            continue
        presets = list(dict.fromkeys(p for p, _ in matrix))
        for p in presets if "preset" in claim.varies_with else presets[:1]:
            cells = {s: v for (pp, s), rows in matrix.items() if pp == p for c, v in rows if c.id == claim.id}
            t = cells.get(test)
            if t is None or t.verdict not in JUDGED:
                continue
            hand = {}
            for s, v in cells.items():
                if s != test and v.verdict in JUDGED and v.evaluation not in {h["evaluation"] for h in hand.values()}:
                    hand[s] = {"scene_set": s, "verdict": v.verdict, "evidence": v.evidence, "evaluation": v.evaluation}
            if any(h["verdict"] != t.verdict for h in hand.values()):
                out.append({"claim": claim.id, "preset": p,
                            "test": {"verdict": t.verdict, "evidence": t.evidence, "evaluation": t.evaluation},
                            "hand_built": list(hand.values())})
    return out
