"""Plane tracks over epochs: one landmark id per physical plane, from SDA associations.

Every observation (epoch k, plane index i) is a node of a union-find forest; each strict
association between epoch ``k - delta`` and ``k`` (delta = 1..D) joins two nodes. Joins run
online, epoch by epoch, smallest delta first, and are refused (counted as conflicts) when

- the two tracks already hold observations of a common epoch (a track is injective: one
  plane per epoch), or
- both tracks are already landmarks in the graph (their factors could not be merged in a
  fixed-lag smoother; batch and windowed smoothing share this rule, so they build the
  same graph).

A track becomes a landmark (gets a dense id ``0, 1, ...``) once it spans
``min_epochs`` epochs; the graph builder then adds all its observations.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


class LandmarkTracker:
    """Union-find over plane observations, with landmark ids for tracks seen often enough.

    Attributes:
        observations: (epoch, plane index) of every node, in insertion order.
        conflicts: associations refused by the rules in the module docstring.
    """

    def __init__(self, min_epochs: int = 2) -> None:
        self.min_epochs = min_epochs
        self.observations: list[tuple[int, int]] = []
        self.conflicts = 0
        self._parent: list[int] = []
        self._members: dict[int, list[int]] = {}
        self._pending: dict[int, list[int]] = {}
        self._epochs: dict[int, set[int]] = {}
        self._landmark: dict[int, int] = {}
        self._first_node: dict[int, int] = {}  # epoch -> node id of its plane 0
        self._count: dict[int, int] = {}  # epoch -> number of planes
        self.n_landmarks = 0

    def node(self, epoch: int, index: int) -> int | None:
        """Node id of an observation, or None when unknown."""
        if epoch not in self._first_node or not 0 <= index < self._count[epoch]:
            return None
        return self._first_node[epoch] + index

    def find(self, node: int) -> int:
        """Root of ``node``'s track (path halving)."""
        parent = self._parent
        while parent[node] != node:
            parent[node] = parent[parent[node]]
            node = parent[node]
        return node

    def _union(self, a: int, b: int) -> bool:
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return True
        if self._epochs[ra] & self._epochs[rb] or (ra in self._landmark and rb in self._landmark):
            self.conflicts += 1
            return False
        if len(self._members[ra]) < len(self._members[rb]):
            ra, rb = rb, ra
        self._parent[rb] = ra
        self._members[ra] += self._members.pop(rb)
        self._pending[ra] += self._pending.pop(rb)
        self._epochs[ra] |= self._epochs.pop(rb)
        if rb in self._landmark:
            self._landmark[ra] = self._landmark.pop(rb)
        return True

    def add_epoch(
        self, epoch: int, n_planes: int, associations: Mapping[int, np.ndarray]
    ) -> list[int]:
        """Add epoch ``epoch``'s planes and their associations to earlier epochs.

        Args:
            epoch: index of the new epoch (increasing from call to call).
            n_planes: number of planes in it.
            associations: ``delta -> (M, 2)`` int array of (plane index in epoch
                ``epoch - delta``, plane index in ``epoch``).

        Returns:
            The roots of the tracks this epoch's planes belong to, in the order of the
            planes; see :meth:`members` and :meth:`landmark`.
        """
        start = len(self._parent)
        self._first_node[epoch] = start
        self._count[epoch] = n_planes
        for i in range(n_planes):
            node = start + i
            self._parent.append(node)
            self._members[node] = [node]
            self._pending[node] = [node]
            self._epochs[node] = {epoch}
            self.observations.append((epoch, i))
        for delta in sorted(associations):
            pairs = np.asarray(associations[delta], dtype=int).reshape(-1, 2)
            for i_prev, i_curr in pairs:
                prev = self.node(epoch - delta, int(i_prev))
                curr = self.node(epoch, int(i_curr))
                if prev is not None and curr is not None:
                    self._union(prev, curr)
        return [self.find(start + i) for i in range(n_planes)]

    def members(self, root: int) -> list[tuple[int, int]]:
        """(epoch, plane index) of the observations of a track, by node id."""
        return [self.observations[n] for n in sorted(self._members[root])]

    def take_pending(self, root: int) -> list[tuple[int, int]]:
        """(epoch, plane index) of the track's observations not taken yet, by node id.

        They are taken: a later call returns only observations added (or merged in) since.
        """
        nodes, self._pending[root] = self._pending[root], []
        return [self.observations[n] for n in sorted(nodes)]

    def put_back(self, root: int, observations: list[tuple[int, int]]) -> None:
        """Return observations to the track's pending list (not used yet)."""
        self._pending[root] += [self._first_node[e] + i for e, i in observations]

    def landmark(self, root: int) -> int | None:
        """Landmark id of a track, promoting it when it spans ``min_epochs`` epochs."""
        if root not in self._landmark and len(self._epochs[root]) >= self.min_epochs:
            self._landmark[root] = self.n_landmarks
            self.n_landmarks += 1
        return self._landmark.get(root)
