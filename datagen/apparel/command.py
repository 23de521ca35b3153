"""``mimicbench datagen apparel IN_DATASET OUT_DATASET``."""
from __future__ import annotations

import argparse

from mimicbench.datagen.apparel.stage_params import ApparelOptions
from mimicbench.runtime.options import add_options
from mimicbench.runtime.summary import StageSummary


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
        "file_solver_iterations, file_sleeping, file_warmup, file_body_velocity, file_duplicate_ranges, "
        "file_body_damping, file_contact_cap "
        "(datagen/apparel/params.py).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_options(p, ApparelOptions)
    p.set_defaults(func=run)


def run(params: ApparelOptions) -> StageSummary:
    from mimicbench.datagen.apparel.stage import run_command

    return run_command(params)
