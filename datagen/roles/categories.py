"""Where each character's category came from, for the summaries of ``datagen ingest`` and
``datagen roles``: ``meta.category.source`` is ``inferred`` (:func:`mimicbench.datagen.ingest.category.infer_category`,
or an MMD model's standard bone set), ``map`` (``--category-map``) or ``labels`` (a role-label file)."""
from __future__ import annotations

import json

from mimicbench.schemas.shards import read_table


def category_sources(dataset, ids=None) -> list[tuple[str, str, str, str]]:
    """``(character_id, category, source, rule)`` per character of ``dataset`` (of ``ids`` when
    given), in table order; ``source`` is ``""`` where the meta says nothing (the zoo's own)."""
    t = read_table(dataset, "characters", columns=["character_id", "category", "meta"]).to_pydict()
    out = []
    for cid, cat, meta in zip(t["character_id"], t["category"], t["meta"]):
        if ids is not None and cid not in ids:
            continue
        how = (json.loads(meta) if isinstance(meta, str) else (meta or {})).get("category") or {}
        out.append((cid, cat, how.get("source", ""), (how.get("evidence") or {}).get("rule", "")))
    return out


def inferred_lines(dataset, ids=None) -> list[str]:
    """The summary lines naming the characters whose category was inferred (not given by a map or a
    label file), with the rule that decided; ``unknown`` ones first."""
    rows = [r for r in category_sources(dataset, ids) if r[2] == "inferred"]
    if not rows:
        return []
    rows.sort(key=lambda r: (r[1] != "unknown", r[0]))
    lines = [f"categories inferred from the skeleton ({len(rows)}; a role-label file's category wins, "
             f"see docs/roles.md):"]
    lines += [f"  {cid}: {cat} ({rule})" for cid, cat, _, rule in rows]
    return lines
