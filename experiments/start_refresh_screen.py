"""Which runs ``odometry.start_refresh`` can change at all (issues 11 and 14).

The option acts only through :func:`planodom.odometry.start_epochs.refresh_start`, called
at most once, when the start's :class:`~planodom.odometry.start_epochs.StartEpochs` closes
(the first measured step, or :data:`~planodom.odometry.start_epochs.MAX_EPOCHS` epochs).
Everything else it does is holding the start's epochs, which changes no output. So the
odometry is run with the option on only until the start closes: a run where
``refresh_start`` was not called by then is bit-identical to the option off, and only the
others need the whole run twice (``experiments/first_epochs.py``). Prints one CSV row per
run: the world (2D-rig worlds, 150 epochs' simulation) or built-in scene (``planodom run
--scenario`` defaults: isoclinal rig, continuous motion, seed 0), the noise, whether the
option acts, the epoch where the start closed and the stale epochs extracted again.

    uv run python experiments/start_refresh_screen.py --worlds 100 102 --noise 0.006 0.02
    uv run python experiments/start_refresh_screen.py --scenes paper-loop urban-canyon
"""

from __future__ import annotations

import argparse

import planodom.odometry.start_epochs as start_epochs
from planodom.config import PlanodomConfig
from planodom.odometry import run_odometry


class _Closed(Exception):
    """The start closed: the option can act no more."""


def screened(source, rig=None) -> tuple[bool, int]:  # noqa: ANN001
    """Whether the option acts on ``source`` (an epoch sequence) and where the start closed
    (-1: never)."""
    calls: list[int] = []
    closed = [-1]
    refresh, appended = start_epochs.refresh_start, start_epochs.StartEpochs.appended

    def counting(odo, stale, known, twist, last):  # noqa: ANN001, ANN202
        calls.append(last)
        return refresh(odo, stale, known, twist, last)

    def closing(self, odo, epoch):  # noqa: ANN001, ANN202
        was = self.open
        appended(self, odo, epoch)
        if was and not self.open:
            closed[0] = epoch.index
            raise _Closed

    start_epochs.refresh_start = counting
    start_epochs.StartEpochs.appended = closing  # type: ignore[method-assign]
    try:
        cfg = PlanodomConfig().updated({"odometry.start_refresh": True}, source="screen")
        run_odometry(source, cfg, rig)
    except _Closed:
        pass
    finally:
        start_epochs.refresh_start = refresh
        start_epochs.StartEpochs.appended = appended  # type: ignore[method-assign]
    return bool(calls), closed[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, nargs="*", default=[])
    parser.add_argument("--scenes", nargs="*", default=[])
    parser.add_argument("--noise", nargs="+", default=["0.006", "0.02"],
                        help="worlds: metres; scenes: metres or a preset (lms221)")  # fmt: skip
    parser.add_argument("--epochs", type=int, default=150, help="worlds' epochs")
    args = parser.parse_args()
    print("run,noise,acts,start_closed_at")
    for w in args.worlds:
        from planodom.experiments.generalisation import world_for
        from planodom.simulation.random_world import simulate_world, world_fields

        world = world_for(w)
        for noise in args.noise:
            full = simulate_world(world, float(noise), n_epochs=args.epochs, all_fields=True)
            acts, at = screened(world_fields(world, full))
            print(f"world {w},{noise},{acts},{at}", flush=True)
    for scene in args.scenes:
        from planodom.cli.common import simulate_scene

        for noise in args.noise:
            sim = simulate_scene(scene, "isoclinal", noise, 0, None, "continuous")
            acts, at = screened(sim, sim.rig)
            print(f"{scene},{noise},{acts},{at}", flush=True)


if __name__ == "__main__":
    main()
