"""A built-in scene or procedural world simulated for a command (``simulate``, ``run
--scenario``), its memory checked first for long runs."""

from __future__ import annotations

from typing import Any


def simulate_scene(
    scene: str,
    rig: str | None,
    noise: str,
    seed: int,
    epochs: int | None,
    motion: str,
    handheld: bool = False,
    noise_seed: int | None = None,
):
    from planodom.errors import ConfigError
    from planodom.simulation import simulate_named

    if epochs is not None and epochs < 1:  # before simulating; it named a temporary folder
        raise ConfigError(f"--epochs {epochs}: expected 1 or more (default: one lap)")
    try:
        sigma: float | str = float(noise)
    except ValueError:
        sigma = noise  # a preset name
    if epochs is not None and epochs > MEMORY_CHECK_EPOCHS:
        one = simulate_named(scene, rig, noise=sigma, seed=seed, n_epochs=1, motion=motion,
                             handheld=handheld)  # fmt: skip
        _check_simulation_memory(one, epochs)
    from planodom.cli.common import console

    with console.status(f"simulating {scene} with the {rig or 'drawn'} rig"):
        return simulate_named(scene, rig, noise=sigma, seed=seed, n_epochs=epochs, motion=motion,
                              handheld=handheld, noise_seed=noise_seed)  # fmt: skip


#: Above this many epochs a simulation's memory is estimated (from one simulated epoch)
#: before it runs: every epoch's points and ranges are held until the dataset is written.
MEMORY_CHECK_EPOCHS = 1000


def _check_simulation_memory(one: Any, epochs: int) -> None:
    """Refuse ``--epochs`` whose simulated scans (estimated from the one-epoch run ``one``)
    would not fit in this machine's memory (it ran for minutes, then failed or was killed)."""
    import os

    from planodom.errors import ConfigError

    arrays = [a for s in one.scans for a in (s.points, s.ring, s.t, s.label) if a is not None]
    arrays += [r for per_sensor in one.ranges for r in per_sensor]
    need = epochs * sum(a.nbytes for a in arrays)
    have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > have:
        raise ConfigError(
            f"--epochs {epochs}: the simulated scans would take about {need / 1e9:.3g} GB of "
            f"memory ({need / epochs / 1e6:.2g} MB an epoch), more than this machine's "
            f"{have / 1e9:.3g} GB"
        )
