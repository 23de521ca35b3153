"""How often the matched bones share their hidden role (zoo ground truth), per category pair.

Roles like ``left/upper_arm`` or ``tail/3`` are stored per bone by the zoo and never given to
methods; here they score the matching (M_hung). For each pair:

- ``exact``: share of matched (source, target) bones whose roles are identical;
- ``role_map``: share whose classes in the cross-category role map agree
  (:mod:`mimicbench.datagen.correspond.roles`: arm ~ front leg ~ wing, leg ~ hind leg, spine, neck, ...);
- ``agreement``: ``exact`` within a category, ``role_map`` across categories (the number the
  issue's checks read: humanoid naming styles >= 99%, cross-category pairs >= 80%);
- ``matched``: matched bones over min(K1, K2) (below 1 when bones stay unmatched);
- ``recall``: right matches over the most that could be right one-to-one (per role, or per
  class across categories: the sum over roles of min(count in source, count in target)), so a
  method cannot look good by matching little.

Pairs are grouped by category pair, and humanoid pairs also by naming-style pair
(``meta["naming_style"]``). Each group reports the mean over its pairs; a pair with no match has
no agreement (it counts in ``matched`` and ``recall`` only).
"""
from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np

from mimicbench.datagen.correspond.roles import role_classes

_FIELDS = ("agreement", "exact", "role_map", "matched", "recall")


def pair_role_agreement(source_roles, target_roles, hungarian) -> float | None:
    """Share of matched pairs (P, 2) whose roles are identical; None without roles or matches."""
    if source_roles is None or target_roles is None or len(hungarian) == 0:
        return None
    same = [source_roles[i] == target_roles[j] for i, j in hungarian]
    return float(sum(same) / len(same))


def pair_scores(source, target, hungarian, cache: dict | None = None) -> dict | None:
    """The fields of the module docstring for one pair of records with roles; None without roles.

    ``cache`` (a dict kept across calls) holds each character's roles, role classes and their
    counts by character ID, so a report over many pairs works them out once a character.
    """
    ra, ca, count_ra, count_ca = _roles_of(source, cache)
    rb, cb, count_rb, count_cb = _roles_of(target, cache)
    if ra is None or rb is None:
        return None
    matched = np.asarray(hungarian, dtype=np.int64).reshape(-1, 2)
    h = matched[(ca[matched[:, 0]] != None) & (cb[matched[:, 1]] != None)]  # noqa: E711  a bone without a role: nothing to agree on
    exact = ra[h[:, 0]] == rb[h[:, 1]]
    mapped = ca[h[:, 0]] == cb[h[:, 1]]
    same_category = source.category == target.category
    (count_a, count_b), right = ((count_ra, count_rb), exact) if same_category else ((count_ca, count_cb), mapped)
    possible = sum(min(n, count_b[key]) for key, n in count_a.items())

    def share(xs):  # no match: nothing to agree on
        return float(np.mean(xs)) if len(xs) else None

    return {"agreement": share(right), "exact": share(exact), "role_map": share(mapped),
            "matched": len(matched) / min(len(ra), len(rb)), "recall": (int(right.sum()) / possible) if possible else 1.0}


def _roles_of(record, cache: dict | None) -> tuple:
    """(roles (K,) object array, role classes (K,), Counter of roles, Counter of classes), or Nones."""
    key = record.character_id
    if cache is not None and key in cache:
        return cache[key]
    roles = record.bone_roles
    if roles is None or not any(roles):
        out = (None, None, None, None)
    else:
        roles = list(roles)
        classes = role_classes(roles, record.category)
        out = (np.array(roles, dtype=object), np.array(classes, dtype=object), Counter(r for r in roles if r),
               Counter(c for c in classes if c is not None))
    if cache is not None:
        cache[key] = out
    return out


def _style(record) -> str:
    return (record.meta or {}).get("naming_style", "?")


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _summary(groups: dict) -> dict:
    return {k: {"pairs": len(v), **{f: _mean(s[f] for s in v) for f in _FIELDS}} for k, v in sorted(groups.items())}


def role_agreement_report(records_by_id: dict, pairs: list, method: dict | None = None) -> dict:
    """``{"by_category": {"humanoid->bird": {"pairs": n, "agreement": x, ...}}, "humanoid_styles": {...},
    "humanoid_cross_style_agreement": x, "cross_category_agreement": x, "method": {...}}``."""
    by_cat, by_style, cross, cache = defaultdict(list), defaultdict(list), [], {}
    for p in pairs:
        a, b = records_by_id[p.source_id], records_by_id[p.target_id]
        scores = pair_scores(a, b, p.hungarian, cache)
        if scores is None:
            continue
        by_cat[f"{a.category}->{b.category}"].append(scores)
        if a.category != b.category:
            cross.append(scores)
        if a.category == b.category == "humanoid" and _style(a) != _style(b):
            by_style[f"{_style(a)}->{_style(b)}"].append(scores)
    styles = _summary(by_style)
    return {"method": method, "by_category": _summary(by_cat), "humanoid_styles": styles,
            "humanoid_cross_style_agreement": _mean(s["agreement"] for v in by_style.values() for s in v),
            "cross_category_agreement": _mean(s["agreement"] for s in cross)}


def format_report(report: dict) -> str:
    name = (report.get("method") or {}).get("name", "?")
    lines = [f"role agreement of the matches (method {name}; exact roles within a category, role-map classes "
             "across; matched = share of min(K1, K2) matched; recall = right / possible):"]

    def pct(x):
        return "   n/a" if x is None else f"{x:6.1%}"

    for key, v in report["by_category"].items():
        lines.append(f"  {key:24s} {pct(v['agreement'])}  matched {pct(v['matched'])}  recall {pct(v['recall'])}"
                     f"  ({v['pairs']} pairs)")
    if report.get("cross_category_agreement") is not None:
        lines.append(f"  all cross-category pairs: {pct(report['cross_category_agreement'])}")
    if report["humanoid_styles"]:
        lines.append("humanoids across naming styles:")
        for key, v in report["humanoid_styles"].items():
            lines.append(f"  {key:24s} {pct(v['agreement'])}  ({v['pairs']} pairs)")
        lines.append(f"  all cross-style humanoid pairs: {pct(report['humanoid_cross_style_agreement'])}")
    return "\n".join(lines)
