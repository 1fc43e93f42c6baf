"""The simulated runs the experiments share: a built-in scene, the isoclinal rig, a noise level.

:class:`Simulation` says how every run of an experiment is simulated (seed, length, motion);
:func:`simulate_level` simulates one scene at one noise level and extracts its planes once,
so that the estimators compared on it share them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, invert_transform
from planodom.simulation import SimulatedRun, simulate_named


@dataclass(frozen=True)
class Simulation:
    """How an experiment simulates its runs.

    Attributes:
        seed: noise seed. n_epochs: epochs per run (None: one lap / the whole street).
        motion: "snapshot" (the paper's simulator: every sweep of an epoch cast from one
            pose, no deskewing) or "continuous".
    """

    seed: int = 1
    n_epochs: int | None = None
    motion: str = "snapshot"

    def __post_init__(self) -> None:
        # 0 epochs ended in an IndexError, 1 in tables of NaN: the errors are of steps
        if self.n_epochs is not None and not self.n_epochs >= 2:
            raise ConfigError(
                f"--epochs {self.n_epochs}: an experiment measures the steps between "
                "epochs, so it needs 2 or more"
            )


@dataclass(frozen=True, eq=False)
class SimulatedLevel:
    """One scene at one noise level, simulated with the isoclinal rig.

    Attributes:
        scene, noise (m): what was simulated. sim: the run. gt_poses: (E, 4, 4) truth
        relative to its first pose. planes: per epoch, the extracted planes (base frame),
        or None when not extracted. extraction_s: wall time of the extraction, s.
    """

    scene: str
    noise: float
    sim: SimulatedRun
    gt_poses: np.ndarray
    planes: list[list[Plane]] | None
    extraction_s: float


def simulate_level(
    scene: str, noise: float, config: PlanodomConfig, simulation: Simulation, extract: bool = True
) -> SimulatedLevel:
    """Simulate ``scene`` at range noise ``noise`` (m); extract its planes with
    ``config.extraction`` unless ``extract`` is False (the odometry then extracts itself)."""
    from planodom.extraction import extract_planes

    sim = simulate_named(scene, "isoclinal", noise=noise, seed=simulation.seed,
                         n_epochs=simulation.n_epochs, motion=simulation.motion)  # fmt: skip
    gt = invert_transform(sim.poses[0])[None] @ sim.poses
    c0 = time.perf_counter()
    planes = [extract_planes(scan, config.extraction) for scan in sim] if extract else None
    return SimulatedLevel(scene, noise, sim, gt, planes, time.perf_counter() - c0)


#: The experiments' default: seed 1, the whole lap or street, snapshot motion.
DEFAULT_SIMULATION = Simulation()
