"""The options of ``datagen apparel``: one frozen dataclass, the command line's and the pipeline
file's. The simulation parameters they choose (a ``--params`` file, ``--gravity``) resolve to an
:class:`~mimicbench.datagen.apparel.params.ApparelParams` (:meth:`ApparelOptions.simulation_params`)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from mimicbench.datagen.stage_options import engine_option, not_a_param, quiet_option, ray_address_option
from mimicbench.runtime.argtypes import float_in, nonnegative_int, positive_int
from mimicbench.runtime.options import option

MIN_PHYSICS_FPS = 30.0
DEFAULT_MAX_FAILED = 0.05  # share of clips that may fail (status rows) before the stage exits 1


@dataclass(frozen=True)
class ApparelOptions:
    """What ``datagen apparel`` is asked (``--help`` says each). ``params``: a JSON file of
    simulation parameters or, from Python, the :class:`~mimicbench.datagen.apparel.params.ApparelParams`
    itself; ``batch``: clips between two writes (no command-line option)."""

    in_dataset: str = not_a_param(positional=True, key="in", help="the dataset whose clips are simulated")
    out_dataset: str = not_a_param(positional=True, key="out", help="the output dataset folder")
    fps: float = option(240.0, type=float_in(MIN_PHYSICS_FPS, 10000.0),
                        help=f"physics steps per second of the apparel chains, {MIN_PHYSICS_FPS:g} to 10000 (default "
                             "240); each clip frame gets ceil(fps / clip fps) steps (an MMD model's own bodies step at "
                             "simulation.file_step_rate)")
    relax_frames: int = option(30, type=nonnegative_int,
                               help="frames blending from rest into the clip's first pose (an MMD model's own bodies: "
                                    "holding the first pose), simulated and dropped, >= 0 (default 30)")
    gravity: float | None = not_a_param(
        None, type=float_in(0.0, 1000.0), metavar="M_PER_S2",
        help="gravity along -Y in m/s^2, 0 to 1000 (default 9.8, or the --params file's simulation.gravity); MMD's "
             "own 98 units/s^2 at 0.08 m a unit would be 7.84")
    params: object = not_a_param(None, metavar="FILE", help="JSON file overriding simulation parameters")
    apparel_bones: list | None = option(
        None, nargs="+", metavar="GLOB",
        help="glob patterns on bone names choosing the apparel bones, case-insensitive (e.g. '*hair*' '*skirt*'); the "
             "apparel vertex mask follows the weights. Default: each character's own apparel_bone_mask (the zoo's)")
    max_failed: float = not_a_param(
        DEFAULT_MAX_FAILED, type=float_in(0.0, 1.0), metavar="SHARE",
        help=f"share of the clips (0 to 1) that may fail with a status row while the stage still exits 0 (default "
             f"{DEFAULT_MAX_FAILED:g}; 0: any failed clip makes the exit status 1)")
    jobs: int = not_a_param(1, type=positive_int, help="worker processes, >= 1 (default 1)")
    engine: str = engine_option()
    ray_address: str | None = ray_address_option()
    quiet: bool = quiet_option()
    batch: int = not_a_param(16, cli=False)

    def simulation_params(self):
        """The :class:`~mimicbench.datagen.apparel.params.ApparelParams` these options choose."""
        from mimicbench.datagen.apparel.params import ApparelParams, load_params

        params = self.params if isinstance(self.params, ApparelParams) else load_params(self.params)
        if self.gravity is not None:
            params = dataclasses.replace(params, simulation=dataclasses.replace(params.simulation,
                                                                                gravity=self.gravity))
        return params
