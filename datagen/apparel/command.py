"""``mimicbench datagen apparel IN_DATASET OUT_DATASET``."""
from __future__ import annotations

import argparse
import dataclasses

from mimicbench.engines import add_engine_arguments
from mimicbench.runtime.summary import StageSummary
from mimicbench.runtime.argtypes import float_in, nonnegative_int, positive_int

MIN_PHYSICS_FPS = 30.0
DEFAULT_MAX_FAILED = 0.05  # share of clips that may fail (status rows) before the stage exits 1


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "apparel", help="simulate apparel bone chains (skirts, hair, capes) with Bullet physics",
        description="For every character with apparel bones and every clip, simulate the apparel chains in "
        "pybullet while the body follows the clip, and write the result as a new motion '<clip>@sim' beside the "
        "kinematic one (apparel bones from the simulation, body bones untouched; LBS of the stored transforms "
        "gives the simulated mesh). The body is one kinematic convex piece per body bone; each chain is a "
        "multibody of links (colliding as the convex hulls of the vertices their bones own) on spherical joints "
        "with limits, a spring toward the rest pose, damping, and its "
        "root carried by a constraint moved every step. Each clip first relaxes: --relax-frames frames blending "
        "from rest into the first pose, simulated and dropped (an MMD model's own bodies instead start as MMD's players start "
        "them: reset at the clip's first pose where it is, every velocity zeroed, then held there for the relaxation "
        "frames; their step rate, error reduction, solver iterations and contacts are the simulation.file_* "
        "fields). The stage writes a section on the apparel's accelerations and penetration into OUT_DATASET/CARD.md, "
        "with a plot beside it. Per-clip quality (apparel inside the body, edge "
        "stretch, jitter, secondary motion in % of height) goes in the character's meta['apparel']; chains "
        "that escape the speed bound are put back at rest on their anchors (re-settled, up to "
        "simulation.max_resettles frames a clip, counted in the quality), and a clip whose simulation still "
        "explodes gets a 'failed' status row and keeps its kinematic clip. Deterministic; a "
        "re-run into the same OUT_DATASET resumes. The exit status is 0 while at most --max-failed of the clips "
        "failed (each failure a status row: a dataset build of thousands of clips is not stopped by a few) and 1 "
        "above it. Examples:\n"
        "  mimicbench datagen apparel data/zoo data/zoo_sim\n"
        "  mimicbench datagen apparel data/mine data/mine_sim --apparel-bones '*hair*' '*skirt*' --params phys.json\n\n"
        "--params FILE overrides parameters per apparel kind (skirt, hair, ponytail, cape, coat_tail, default):\n"
        '  {"simulation": {"max_speed": 25}, "kinds": {"hair": {"stiffness": 0.05, "swing_limit": 0.6}}}\n'
        "fields: link_mass, stiffness, damping, strength, linear_damping, angular_damping, swing_limit, "
        "twist_limit, radius_scale, friction, collide_body, collide_chains, axial_inertia, root_contact_frequency, root_hull_from, "
        "contact_frequency, contact_shell; "
        "simulation: gravity, max_speed, solver_iterations, anchor_force, contact_erp, max_joint_velocity, "
        "constraint_erp, piece_mass, piece_velocity, max_resettles, file_contact_frequency, file_step_rate, file_erp, "
        "file_solver_iterations, file_sleeping, file_warmup (datagen/apparel/params.py).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("in_dataset")
    p.add_argument("out_dataset")
    p.add_argument("--fps", type=float_in(MIN_PHYSICS_FPS, 10000.0), default=240.0,
                   help=f"physics steps per second of the apparel chains, {MIN_PHYSICS_FPS:g} to 10000 (default "
                        "240); each clip frame gets ceil(fps / clip fps) steps (an MMD model's own bodies step at "
                        "simulation.file_step_rate)")
    p.add_argument("--relax-frames", type=nonnegative_int, default=30,
                   help="frames blending from rest into the clip's first pose (an MMD model's own bodies: holding the "
                        "first pose), simulated and dropped, >= 0 (default 30)")
    p.add_argument("--gravity", type=float_in(0.0, 1000.0), default=None, metavar="M_PER_S2",
                   help="gravity along -Y in m/s^2, 0 to 1000 (default 9.8, or the --params file's "
                        "simulation.gravity); MMD's own 98 units/s^2 at 0.08 m a unit would be 7.84")
    p.add_argument("--params", default=None, metavar="FILE", help="JSON file overriding simulation parameters")
    p.add_argument("--apparel-bones", nargs="+", default=None, metavar="GLOB",
                   help="glob patterns on bone names choosing the apparel bones, case-insensitive (e.g. '*hair*' "
                        "'*skirt*'); the apparel vertex mask follows the weights. Default: each character's own "
                        "apparel_bone_mask (the zoo's)")
    p.add_argument("--max-failed", type=float_in(0.0, 1.0), default=DEFAULT_MAX_FAILED, metavar="SHARE",
                   help="share of the clips (0 to 1) that may fail with a status row while the stage still exits 0 "
                        f"(default {DEFAULT_MAX_FAILED:g}; 0: any failed clip makes the exit status 1)")
    p.add_argument("--jobs", type=positive_int, default=1, help="worker processes, >= 1 (default 1)")
    add_engine_arguments(p)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    from mimicbench.datagen.apparel.params import load_params
    from mimicbench.engines import engine_from_args
    from mimicbench.datagen.apparel.stage import simulate_dataset
    from mimicbench.datagen.apparel.quality import JITTER_RATIO

    params = load_params(args.params)
    if args.gravity is not None:
        params = dataclasses.replace(params, simulation=dataclasses.replace(params.simulation, gravity=args.gravity))
    s = simulate_dataset(args.in_dataset, args.out_dataset, args.fps, args.relax_frames, params, args.apparel_bones,
                         args.jobs, progress=not args.quiet, engine=engine_from_args(args))

    def fmt(x, digits=3):
        return "n/a" if x is None else round(x, digits)

    print(f"{s['simulated']} clips simulated, {s['reused']} reused, {s['failed']} failed, {s['resettled']} "
          f"re-settled on {s['characters']} "
          f"characters with apparel in {s['seconds']:.1f} s; apparel inside the body {fmt(s['inside_pct_mean'])} % "
          f"(new {fmt(s['new_inside_pct_mean'])} %), secondary motion {fmt(s['secondary_motion_pct_mean'])} % of "
          f"height, max edge stretch {fmt(s['max_edge_stretch'])} -> {args.out_dataset}")
    if s["over_jitter_bound"]:
        n = len(s["over_jitter_bound"])
        print(f"{n} {'clip peaks' if n == 1 else 'clips peak'} above {JITTER_RATIO:g}x the acceleration of the kinematic apparel and "
              f"of the body that touches it (jitter, not a limb's strike): {', '.join(s['over_jitter_bound'][:5])}"
              f"{' ...' if len(s['over_jitter_bound']) > 5 else ''}; their quality is in the characters' "
              f"meta['apparel']")
    share = s["failed"] / max(1, s["simulated"] + s["reused"] + s["failed"])
    if s["failed"]:
        print(f"{s['failed']} failed clips ({100 * share:.1f} % of the clips, --max-failed "
              f"{100 * args.max_failed:g} %): see the status rows in {args.out_dataset}/status; their kinematic "
              f"clips are kept")
    return StageSummary(s["simulated"] + s["reused"], s["failed"], s["seconds"], str(args.out_dataset),
                        exit_code=1 if share > args.max_failed else 0)
