"""Issue 33: are a spin's apparel acceleration peaks over 3x the kinematic peak physical or numerical?

For each ``spin`` clip of a zoo (``mimicbench zoo ... --categories apparel --clip-set dynamic``)
the clip is simulated as the apparel stage does it (:func:`mimicbench.datagen.apparel.setup.simulate_motion`,
its world from :func:`mimicbench.datagen.apparel.setup.character_physics`), and the peak of
:func:`mimicbench.datagen.apparel.quality.clip_quality` (``max_accel``: the largest second difference of an
apparel vertex at the clip's fps, m/s^2) is taken apart at its frame and vertex:

- ``v`` (m/s): the vertex's speed there (central difference);
- ``r`` (m): its distance from the vertical spin axis through the root bone (the hips);
- ``omega`` (rad/s): the root's yaw rate there (central difference of its heading);
- ``v^2/r`` and ``omega^2 r`` (m/s^2): what the vertex's centripetal acceleration would be if it
  went round the axis at its own speed, or with the body;
- ``a_rad`` (m/s^2): the measured acceleration's component toward the axis (horizontal);
- ``nyq``: the share of the energy of the acceleration along the peak's direction, in the 5 frames
  centred at the peak, at the Nyquist frequency (``(sum (-1)^t a_t)^2 / (5 sum a_t^2)``; 1 for a
  pure step-to-step alternation, jitter; about 0 for a smooth swing), and ``flips``: sign changes
  of that component over those 5 frames (0-4);
- the same clip's peak / kinematic peak with the physics at 2x and 4x the rate (480 and 960 Hz)
  with the same physical springs: the springs' per-step shares (stiffness s, damping v,
  :mod:`mimicbench.datagen.apparel.springs`: K = s diag(M0) / dt^2, C = v diag(M0) / dt) scaled to keep K and
  C (s x (dt'/dt)^2, v x dt'/dt), and Bullet's contact and constraint ERP (per-step shares of an
  error) scaled by dt'/dt. A physical peak converges as dt shrinks; a numerical one does not.

Printed: one row per clip over ``--over`` times its kinematic peak at the stage's rate (all
spins with ``--all``), then a one-line summary (clips over at each rate, median ratio, median
share of the peak that v^2/r explains, median Nyquist share). ``--params`` takes the stage's
``--params`` JSON (inline): ``'{"simulation": {"piece_velocity": false}}'`` gives simulation
version 12's static body pieces (issue 33; simulation version 13 gives them their speed).

    mimicbench zoo --out ZOO --characters 40 --categories apparel --seed 711 --clips-per-character 4 \
        --clip-set dynamic --quiet
    PYTHONPATH=. OMP_NUM_THREADS=1 python analyses/apparel_spin_peaks.py ZOO \
        [--params JSON] [--clip spin] [--over 3] [--rates 2 4] [--all] [--characters apparel-0004 ...]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from mimicbench.datagen.apparel.params import ApparelParams, params_from_json
from mimicbench.datagen.apparel.setup import character_physics, simulate_motion
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.shards import read_records

PHYSICS_FPS, RELAX = 240.0, 30  # the stage's defaults (mimicbench datagen apparel)


def params_at_rate(params: ApparelParams, rate: float) -> ApparelParams:
    """``params`` for physics ``rate`` times faster with the same physical springs and error
    correction: stiffness shares / rate^2, damping shares / rate, contact and constraint ERP / rate."""
    kinds = {k: dataclasses.replace(c, stiffness=c.stiffness / rate ** 2, damping=c.damping / rate)
             for k, c in params.kinds.items()}
    sim = dataclasses.replace(params.simulation, contact_erp=params.simulation.contact_erp / rate,
                              constraint_erp=params.simulation.constraint_erp / rate)
    return ApparelParams(sim, kinds)


def yaw(q: np.ndarray) -> np.ndarray:
    """Heading (rad) about +Y of unit quaternions ``q`` (..., 4) (w, x, y, z): the angle of the turned +Z in XZ."""
    w, x, y, z = np.moveaxis(np.asarray(q, np.float64), -1, 0)
    fx, fz = 2 * (x * z + w * y), 1 - 2 * (x * x + y * y)  # the rotated +Z's X and Z components
    return np.arctan2(fx, fz)


def peak_anatomy(posed: np.ndarray, root: np.ndarray, fps: float) -> dict:
    """Take the largest acceleration of vertices ``posed`` (F, A, 3) m at ``fps`` apart.

    ``root`` (F, 7): the root bone's transforms (w, x, y, z, t). Returns the peak (m/s^2), its
    frame (the second difference's middle frame) and vertex, and ``v``, ``r``, ``omega``,
    ``v2_r``, ``w2_r``, ``a_rad``, ``nyq``, ``flips`` as in the module docstring.
    """
    acc = (posed[2:] - 2 * posed[1:-1] + posed[:-2]) * fps ** 2  # (F - 2, A, 3), at frames 1..F-2
    mag = np.linalg.norm(acc, axis=-1)
    i, a = np.unravel_index(int(np.argmax(mag)), mag.shape)
    f = i + 1
    v = float(np.linalg.norm(posed[f + 1, a] - posed[f - 1, a]) * fps / 2)
    outward = posed[f, a] - root[f, 4:]
    outward[1] = 0.0
    r = float(np.linalg.norm(outward))
    heading = np.unwrap(yaw(root[:, :4]))
    omega = float((heading[f + 1] - heading[f - 1]) * fps / 2)
    direction = acc[i, a] / mag[i, a]
    window = acc[max(0, i - 2):i + 3, a] @ direction  # the acceleration along the peak's direction
    alternating = (-1.0) ** np.arange(len(window))
    return {"peak": float(mag[i, a]), "frame": int(f), "vertex": int(a), "v": v, "r": r, "omega": omega,
            "v2_r": v * v / max(r, 1e-9), "w2_r": omega * omega * r,
            "a_rad": float(-acc[i, a] @ outward / max(r, 1e-9)),
            "nyq": float((window @ alternating) ** 2 / (len(window) * (window @ window))),
            "flips": int(np.sum(np.sign(window[1:]) != np.sign(window[:-1])))}


def simulate(record, motion, params: ApparelParams, rate: float) -> tuple[np.ndarray, dict]:
    """The clip (F, K, 7) of ``motion`` simulated at ``rate`` x the stage's physics rate, and its quality."""
    p = params_at_rate(params, rate) if rate != 1 else params
    physics = character_physics(record, record.apparel_bone_mask, record.apparel_vertex_mask, p)
    sim, quality = simulate_motion(record, physics, motion, p, PHYSICS_FPS * rate, RELAX)
    return np.asarray(sim.transforms, np.float64), quality


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("zoo", help="a zoo folder with apparel characters and dynamic clips")
    ap.add_argument("--clip", default="spin", help="clip name to study (default spin)")
    ap.add_argument("--over", type=float, default=3.0, help="ratio of peaks to study (default 3)")
    ap.add_argument("--rates", type=float, nargs="+", default=[2.0, 4.0], help="physics rates to re-run at (x 240 Hz)")
    ap.add_argument("--all", action="store_true", help="a row for every clip, not only those over")
    ap.add_argument("--characters", nargs="*", help="only these character ids (apparel-0004 ...)")
    ap.add_argument("--params", default="{}", help="the stage's --params JSON, inline (default: the defaults)")
    args = ap.parse_args()

    params = params_from_json(json.loads(args.params))
    characters = {r.character_id: r for r in read_records(args.zoo, "characters")}
    motions = [m for m in read_records(args.zoo, "motions") if m.name == args.clip
               and (not args.characters or m.character_id.split("/")[-1] in args.characters)]
    motions.sort(key=lambda m: m.character_id)
    head = (f"{'clip':<22}{'ratio':>6}{'peak':>7}{'kin':>6}{'frame':>6}{'v':>6}{'r':>6}{'omega':>7}{'v2/r':>7}"
            f"{'w2r':>7}{'a_rad':>7}{'nyq':>6}{'flips':>6}{'new_in':>7}" + "".join(f"{f'x{r:g}':>7}" for r in args.rates))
    print(head)
    rows, start = [], time.process_time()
    for motion in motions:
        record = characters[motion.character_id]
        sim, q = simulate(record, motion, params, 1.0)
        ratio = q["max_accel"] / q["max_accel_kinematic"]
        if ratio <= args.over and not args.all:
            rows.append({"ratio": ratio, "worst": q["new_inside_max_pct"]})
            continue
        mask = np.asarray(record.apparel_vertex_mask, bool)
        posed = linear_blend_skinning(record.vertices, record.keypoints, record.weights, sim)[:, mask].astype(np.float64)
        root = int(np.flatnonzero(np.asarray(record.parents) < 0)[0])
        anatomy = peak_anatomy(posed, sim[:, root], motion.fps)
        faster = []
        for rate in args.rates:
            _, qr = simulate(record, motion, params, rate)
            faster.append(qr["max_accel"] / qr["max_accel_kinematic"])
        rows.append({"ratio": ratio, "worst": q["new_inside_max_pct"], "faster": faster, **anatomy})
        a = anatomy
        print(f"{motion.motion_id:<22}{ratio:6.2f}{a['peak']:7.1f}{q['max_accel_kinematic']:6.1f}{a['frame']:6d}"
              f"{a['v']:6.2f}{a['r']:6.3f}{a['omega']:7.2f}{a['v2_r']:7.1f}{a['w2_r']:7.1f}{a['a_rad']:7.1f}"
              f"{a['nyq']:6.2f}{a['flips']:6d}{q['new_inside_max_pct']:7.2f}" + "".join(f"{x:7.2f}" for x in faster),
              flush=True)
    over = [r for r in rows if r["ratio"] > args.over]
    studied = [r for r in rows if "faster" in r]
    worst = [r["worst"] for r in rows]
    summary = (f"{len(over)} of {len(rows)} {args.clip} clips over {args.over:g}x at {PHYSICS_FPS:g} Hz "
               f"(median ratio {np.median([r['ratio'] for r in rows]):.2f}; worst frame inside mean "
               f"{np.mean(worst):.2f} %, largest {np.max(worst):.2f} %)")
    for k, rate in enumerate(args.rates):
        summary += (f"; at x{rate:g}: {sum(r['faster'][k] > args.over for r in studied)} of {len(studied)} "
                    f"(median {np.median([r['faster'][k] for r in studied]):.2f})" if studied else "")
    if studied:
        summary += (f"; median v^2/r / peak {np.median([r['v2_r'] / r['peak'] for r in studied]):.2f}, a_rad / peak "
                    f"{np.median([r['a_rad'] / r['peak'] for r in studied]):.2f}, Nyquist share "
                    f"{np.median([r['nyq'] for r in studied]):.2f}")
    print(summary + f"; {time.process_time() - start:.0f} CPU s")


if __name__ == "__main__":
    main()
