"""``mimicbench render DATASET CHARACTER_ID [--motion M --frame F] --out PNG``."""
from __future__ import annotations

import argparse


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "render", help="render a character (at rest or posed) to a PNG through Blender",
        description="Render one character of a dataset with Blender's Workbench engine (in a child process "
        "with a timeout), at rest or posed by one frame of one of its motions, framed from its bounding box, "
        "labelled with its ID and pose. Needs bpy (the `blender` extra). Examples:\n"
        "  mimicbench render data/zoo zoo/quadruped-0000 --out quadruped.png\n"
        "  mimicbench render data/zoo zoo/humanoid-0000 --motion walk --frame 12 --out walk12.png\n"
        "  mimicbench render data/zoo --contact-sheet --out data/zoo/card/contact_sheet.png",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset", help="dataset folder (with characters/ and motions/)")
    p.add_argument("character_id", nargs="?", help="e.g. zoo/humanoid-0000 or assets/Fox")
    p.add_argument("--motion", default=None, help="motion name or motion_id (default: the rest pose)")
    p.add_argument("--frame", type=int, default=0, help="frame of the motion (default 0)")
    p.add_argument("--out", required=True, help="PNG file to write")
    p.add_argument("--size", type=int, default=512, help="image width and height in pixels (default 512)")
    p.add_argument("--contact-sheet", action="store_true",
                   help="instead of one character, every character of the dataset on one labelled sheet")
    p.add_argument("--timeout", type=float, default=None, help="seconds before Blender is stopped")
    p.set_defaults(func=run)


def run(args) -> int:
    import time

    from mimicbench.datagen.render.character import character_panel
    from mimicbench.datagen.render.render import RenderError, render_sheet
    from mimicbench.schemas.errors import UserError

    start = time.perf_counter()
    try:
        if args.contact_sheet:
            from mimicbench.datagen.render.contact_sheet import write_contact_sheet

            out = write_contact_sheet(args.dataset, args.out, panel_px=min(args.size, 320), timeout=args.timeout)
            what = "contact sheet"
        else:
            if not args.character_id:
                raise UserError("render: expected CHARACTER_ID (or --contact-sheet); see `mimicbench render --help`")
            panel = character_panel(args.dataset, args.character_id, args.motion, args.frame)
            out = render_sheet([panel], args.out, width=args.size, height=args.size, timeout=args.timeout)
            what = args.character_id
    except (KeyError, IndexError, RenderError) as exc:  # unknown ID, motion or frame; Blender missing or failed
        raise UserError(f"render: {exc.args[0] if exc.args else exc}") from exc
    print(f"rendered {what} in {time.perf_counter() - start:.1f} s -> {out}")
    return 0
