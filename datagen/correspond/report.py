"""How often the Hungarian matching pairs bones of the same hidden role (zoo ground truth).

Roles like ``left/upper_arm`` or ``tail/3`` are stored per bone by the zoo and never given to
methods; here they measure the text-guided matching. Agreement of one pair is the share of its
matched (source, target) bones whose roles are equal. Pairs are grouped by category pair, and
humanoid pairs also by naming-style pair (``meta["naming_style"]``).
"""
from __future__ import annotations

from collections import defaultdict


def pair_role_agreement(source_roles, target_roles, hungarian) -> float | None:
    """Share of matched pairs (P, 2) whose roles agree; None without roles."""
    if source_roles is None or target_roles is None or len(hungarian) == 0:
        return None
    same = [source_roles[i] == target_roles[j] for i, j in hungarian]
    return float(sum(same) / len(same))


def _style(record) -> str:
    return (record.meta or {}).get("naming_style", "?")


def role_agreement_report(records_by_id: dict, pairs: list) -> dict:
    """``{"by_category": {"humanoid->bird": {"pairs": n, "agreement": x}}, "humanoid_styles": {...}}``."""
    by_cat, by_style = defaultdict(list), defaultdict(list)
    for p in pairs:
        a, b = records_by_id[p.source_id], records_by_id[p.target_id]
        agree = pair_role_agreement(a.bone_roles, b.bone_roles, p.hungarian)
        if agree is None:
            continue
        by_cat[f"{a.category}->{b.category}"].append(agree)
        if a.category == b.category == "humanoid" and _style(a) != _style(b):
            by_style[f"{_style(a)}->{_style(b)}"].append(agree)

    def summary(groups):
        return {k: {"pairs": len(v), "agreement": sum(v) / len(v)} for k, v in sorted(groups.items())}

    styles = summary(by_style)
    all_style = [x for v in by_style.values() for x in v]
    return {"by_category": summary(by_cat), "humanoid_styles": styles,
            "humanoid_cross_style_agreement": (sum(all_style) / len(all_style)) if all_style else None}


def format_report(report: dict) -> str:
    lines = ["role agreement of Hungarian matches (share of matched bones with the same hidden role):"]
    for key, v in report["by_category"].items():
        lines.append(f"  {key:28s} {v['agreement']:6.1%}  ({v['pairs']} pairs)")
    if report["humanoid_styles"]:
        lines.append("humanoids across naming styles:")
        for key, v in report["humanoid_styles"].items():
            lines.append(f"  {key:28s} {v['agreement']:6.1%}  ({v['pairs']} pairs)")
        lines.append(f"  all cross-style humanoid pairs: {report['humanoid_cross_style_agreement']:.1%}")
    return "\n".join(lines)
