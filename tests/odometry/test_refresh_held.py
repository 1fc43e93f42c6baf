"""A refresh after an unresolved epoch that takes the reference's pair away is undone."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.odometry.refresh_held import held_refresh


@dataclass
class _Ref:
    paired: bool

    def has_pair(self, association: object) -> bool:
        return self.paired


@dataclass
class _Odometry:
    """The members :func:`held_refresh` uses: a reference whose pair a refresh with a
    yaw rate above 0.1 rad/s takes away (as the held 8.1 deg/s did on world 192)."""

    config: PlanodomConfig
    ref: _Ref = field(default_factory=lambda: _Ref(True))
    calls: list[str] = field(default_factory=list)

    def _reference(self) -> _Ref:
        return self.ref

    def _refresh_reference(self, twist: np.ndarray) -> bool:
        self.calls.append("refresh")
        self._before = self.ref.paired
        self.ref.paired = self.ref.paired and bool(abs(twist[2]) <= 0.1)
        return True

    def _restore_reference(self) -> None:
        self.calls.append("restore")
        self.ref.paired = self._before


def _odometry(on: bool, paired: bool = True) -> _Odometry:
    config = PlanodomConfig().updated({"odometry.refresh_keep_pair_held": on})
    return _Odometry(config, _Ref(paired))


TWIST_LOSES = np.array([0.0, 0.0, 0.142, 4.0, 0.0, 0.0])
TWIST_KEEPS = np.array([0.0, 0.0, 0.08, 4.0, 0.0, 0.0])


def test_lost_pair_after_unresolved_is_undone() -> None:
    odo = _odometry(True)
    assert held_refresh(odo, unresolved=True)(TWIST_LOSES) is False  # type: ignore[arg-type]
    assert odo.calls == ["refresh", "restore"] and odo.ref.paired


@pytest.mark.parametrize(("on", "unresolved"), [(False, True), (True, False), (False, False)])
def test_other_refreshes_are_left_alone(on: bool, unresolved: bool) -> None:
    odo = _odometry(on)
    assert held_refresh(odo, unresolved)(TWIST_LOSES) is True  # type: ignore[arg-type]
    assert odo.calls == ["refresh"] and not odo.ref.paired


@pytest.mark.parametrize(("paired", "twist"), [(True, TWIST_KEEPS), (False, TWIST_LOSES)])
def test_no_pair_lost_is_kept(paired: bool, twist: np.ndarray) -> None:
    odo = _odometry(True, paired)
    assert held_refresh(odo, unresolved=True)(twist) is True  # type: ignore[arg-type]
    assert odo.calls == ["refresh"] and odo.ref.paired is paired
