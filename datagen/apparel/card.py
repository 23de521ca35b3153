"""The apparel section of a dataset card: per character and clip, how hard the simulated apparel
moves against the kinematic clip, how much of it enters the body, and how often chains re-settled.

``datagen apparel`` writes it into OUT/CARD.md (between :data:`BEGIN` and :data:`END`, replaced on
a re-run) with a plot beside it, ``apparel_accel.png``: each clip's peak apparel acceleration
against its jitter bound (the larger of the apparel's own kinematic peak and the kinematic peak of
the body that touches it, :func:`~mimicbench.datagen.apparel.quality.over_jitter_bound`), with the 1x and
:data:`~mimicbench.datagen.apparel.quality.JITTER_RATIO` x lines. Figures come from the clips' quality
(:mod:`mimicbench.datagen.apparel.quality`): accelerations in m/s^2, penetration as the percent of apparel
vertices inside the body that are outside it at rest (mean over frames and worst frame).
"""
from __future__ import annotations

from pathlib import Path

from mimicbench.datagen.apparel.quality import JITTER_RATIO, over_jitter_bound
from mimicbench.datagen.zoo.card import put_card_section

BEGIN = "<!-- apparel quality -->"
END = "<!-- /apparel quality -->"
PLOT = "apparel_accel.png"


def jitter_bound(q: dict) -> float:
    """The kinematic peak a clip's ``max_accel`` is compared with (m/s^2)."""
    return max(q["max_accel_kinematic"], q.get("max_accel_kinematic_touching", 0.0))


def render_section(clips: dict[str, dict], plot: str | None) -> str:
    """Markdown of the apparel section; ``clips`` is ``{"<character>/<clip>": quality}``."""
    over = sorted(k for k, q in clips.items() if over_jitter_bound(q))
    lines = [BEGIN, "## Apparel simulation", "",
             f"{len(clips)} simulated clips; {len(over)} over the jitter bound ({JITTER_RATIO:g}x the larger of the "
             f"apparel's and the touching body's kinematic peak); "
             f"{sum(q['resettles'] > 0 for q in clips.values())} with re-settled chains. Accelerations in m/s^2; "
             "penetration: percent of apparel vertices inside the body that are outside it at rest.", "",
             "| character / clip | peak | p99 | kinematic peak (apparel / touching body) | peak / bound | "
             "penetration mean % | worst frame % | re-settles |",
             "|---|---|---|---|---|---|---|---|"]
    for key in sorted(clips):
        q = clips[key]
        bound = jitter_bound(q)
        ratio = q["max_accel"] / bound if bound > 0 else float("inf")
        lines.append(f"| {key} | {q['max_accel']:.1f} | {q['p99_accel']:.1f} | {q['max_accel_kinematic']:.1f} / "
                     f"{q.get('max_accel_kinematic_touching', 0.0):.1f} | {ratio:.2f}{' (over)' if key in over else ''} "
                     f"| {q['new_inside_pct']:.2f} | {q['new_inside_max_pct']:.2f} | {q['resettles']} |")
    if plot:
        lines += ["", f"![peak apparel acceleration against the jitter bound]({plot})"]
    lines.append(END)
    return "\n".join(lines) + "\n"


def plot_peaks(clips: dict[str, dict], path: Path) -> None:
    """Scatter of each clip's peak (and p99) apparel acceleration against its jitter bound, log axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = sorted(clips)
    bound = [max(jitter_bound(clips[k]), 1e-3) for k in keys]
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.scatter(bound, [max(clips[k]["max_accel"], 1e-3) for k in keys], s=18, label="peak")
    ax.scatter(bound, [max(clips[k]["p99_accel"], 1e-3) for k in keys], s=10, marker="x", label="p99")
    lo, hi = min(bound), max(bound)
    xs = [lo * 0.8, hi * 1.25]
    ax.plot(xs, xs, "k:", lw=1, label="1x kinematic peak")
    ax.plot(xs, [x * JITTER_RATIO for x in xs], "r--", lw=1, label=f"{JITTER_RATIO:g}x (jitter bound)")
    for k, b in zip(keys, bound):
        if over_jitter_bound(clips[k]):
            ax.annotate(k.rsplit("/", 1)[-1], (b, clips[k]["max_accel"]), fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("kinematic peak: apparel or touching body (m/s^2)")
    ax.set_ylabel("simulated apparel acceleration (m/s^2)")
    ax.set_title("apparel acceleration per clip")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)


def write_apparel_card(out_dir, clips: dict[str, dict]) -> Path:
    """Put the apparel section (and its plot, when any clip was simulated) into ``out_dir``/CARD.md."""
    root = Path(out_dir)
    plot = None
    if clips:
        plot_peaks(clips, root / PLOT)
        plot = PLOT
    put_card_section(root / "CARD.md", BEGIN, END, render_section(clips, plot))
    return root / "CARD.md"
