"""How a bag was read, in the lines a user should check: :func:`bag_notes`.

None of these stops the reading (the data may be right), but each changes what the
odometry gets without the user having asked for it, so the CLI warns of each and lists
them in ``metrics.json``.
"""

from __future__ import annotations

import numpy as np

from planodom.datasets.bag_beam_notes import beam_notes
from planodom.datasets.bag_gt import gt_notes
from planodom.datasets.bag_index import BagIndex, TopicIndex
from planodom.datasets.bag_msgs import LASER_TYPES
from planodom.datasets.bag_ring_order import ring_order_note
from planodom.datasets.bag_rings import stray_note
from planodom.datasets.bag_time_notes import one_time_notes, unread_time_note


def bag_notes(
    index: BagIndex, chosen: bool, gt_topic: str | None = None, echo: str = "first"
) -> list[str]:
    """One line each (see the module docstring), naming the topic and what to do.

    - a cloud topic's time offsets read in a unit other than the documented one, or not
      clear-cut (:mod:`planodom.datasets.bag_time_units`);
    - a cloud topic whose clouds change layout: times in several fields or types (each
      read in its own unit), some clouds without the time field the others have (their
      points at the stamp) or without the ring field;
    - a topic whose messages name several frames (each read in its own);
    - messages stamped before the one recorded before them on their topic (a clock reset:
      the epochs are in stamp order, not the recording's);
    - messages without a header stamp (0), for which the bag's record time stands;
    - a scan topic none of whose messages holds a point (left out of the epochs when
      another topic has points), or some of whose messages hold none (left out of the
      epochs: they would place epochs without points), or the only scan topic some of
      whose LaserScans hold no return (left out likewise); a 2D scan topic none of whose
      scans holds a return (kept: its stamps keep the rig's timing), unless its range
      limits are swapped (said alone);
    - a 2D scan topic whose beam count changes, whose MultiEchoLaserScans carry no
      intensities under ``echo`` strongest, whose range limits are swapped or whose
      ``time_increment`` is 0 (:mod:`planodom.datasets.bag_beam_notes`);
    - points whose ring id is their ring field type's largest value ("no ring"), or no ring
      of the lidar's numbering (:mod:`planodom.datasets.bag_rings`), left out;
    - points a Livox lidar marks as high confidence noise (their ``tag``), left out;
    - messages recorded twice (same topic, stamp and content), read once;
    - several point-cloud topics with points merged into each epoch when none was ``chosen``
      (``--topic``): a raw and a filtered cloud of one lidar would be read twice (each with
      the sweeps it gives the epochs);
    - reference poses (``gt_topic``) left out for a NaN, infinite or zero-quaternion value,
      naming several frame pairs, recorded twice (read once), or repeating a stamp with
      another pose (the last is used).
    """
    counts = np.bincount(index.sweep_topic, minlength=len(index.topics))
    some_points = not all(t.pointless for t in index.topics)
    notes = []
    for k, (t, sweeps) in enumerate(zip(index.topics, counts, strict=True)):
        notes += [f"topic '{t.name}': {u.note}" for u in t.time_units.values() if u.note]
        notes += _layout_notes(t)
        notes += _frame_and_order_notes(index, k)
        if t.unstamped:
            notes.append(
                f"topic '{t.name}': {t.unstamped} of {sweeps} messages have no header stamp "
                "(0): the bag's record time stands for it, late by the message's transport"
            )
        notes += _empty_notes(t, sweeps, some_points, len(index.topics))
        notes += beam_notes(t.name, t.sweeps, t.beams, echo) + _point_notes(t)
        if t.duplicates:
            notes.append(
                f"topic '{t.name}': {t.duplicates} of {sweeps} messages recorded twice (the "
                "stamp and content of an earlier one: merged or overlapping recordings?), "
                "read once"
            )
    read = np.bincount(index.sweep_topic[index.in_epochs()], minlength=len(index.topics))
    clouds = [
        (t, n)
        for t, n in zip(index.topics, read, strict=True)
        if t.msgtype not in LASER_TYPES and not t.pointless  # a topic without points adds none
    ]
    if not chosen and len(clouds) > 1:
        shown = ", ".join(f"'{t.name}' ({t.frames[0]}, {n} sweeps)" for t, n in clouds)
        notes.append(
            f"{len(clouds)} point-cloud topics read and merged into each epoch: {shown}; if "
            "they are not separate lidars (one is the other filtered or deskewed), choose "
            "with --topic"
        )
    return notes + gt_notes(index.gt_read, gt_topic)


def _empty_notes(t: TopicIndex, sweeps: int, some_points: bool, topics: int) -> list[str]:
    """Topic ``t``'s notes on its messages without a point or a return (``sweeps``
    messages; ``some_points``: some topic has points; ``topics``: the scan topics read)."""
    notes: list[str] = []
    if t.pointless:
        notes.append(
            f"topic '{t.name}': none of its {sweeps} messages holds a point (the sensor "
            "off, or everything filtered out?)"
            + ("; left out of the epochs" if some_points else "")
        )
    elif t.empty:
        notes.append(
            f"topic '{t.name}': {t.empty} of {sweeps} messages hold no point (dropouts, "
            "or everything filtered out?); left out of the epochs"
        )
    elif t.msgtype in LASER_TYPES and sweeps and t.blank == sweeps > t.beams.swapped:
        notes.append(
            f"topic '{t.name}': none of its {sweeps} scans holds a return (the scanner "
            "blocked or off, or its range limits?): it adds no point to the epochs"
        )
    elif t.blank and topics == 1 and t.blank < sweeps:
        notes.append(
            f"topic '{t.name}': {t.blank} of {sweeps} scans hold no return (open space, "
            "or everything beyond range_max?); left out of the epochs"
        )
    return notes


def _frame_and_order_notes(index: BagIndex, k: int) -> list[str]:
    """Topic ``k``'s notes on its messages naming several frames and stamped out of order."""
    t, notes = index.topics[k], []
    if len(t.frames) > 1:
        notes.append(
            f"topic '{t.name}': its messages name {len(t.frames)} frames "
            f"({', '.join(t.frames)}: a driver relaunched with another frame_id?); each "
            f"is read in its own frame, the rig's sensor origin is {t.frames[0]}'s"
        )
    back = _stamped_back(index, k)
    if back:
        notes.append(f"topic '{t.name}': {back}")
    return notes


def _layout_notes(t: TopicIndex) -> list[str]:
    """A cloud topic's notes on clouds of other layouts than the rest (a driver relaunched
    with other fields): times in several fields or types, clouds without a time or ring
    field where others have one."""
    notes, clouds = [], t.timed + t.untimed
    if len(t.times) > 1:
        shown = ", ".join(f"'{v.name}' ({v.dtype}) in {len(v.sweeps)}" for v in t.times.values())
        notes.append(
            f"topic '{t.name}': its clouds hold their point times in {len(t.times)} fields or "
            f"types ({shown} clouds: a driver relaunched with another layout?); each is read "
            "in its own unit"
        )
    if t.timed and t.untimed:
        notes.append(
            f"topic '{t.name}': {t.untimed} of {clouds} clouds have no time field, the others "
            "have one (a driver relaunched with another layout?); their points are taken at "
            "their message's stamp, not deskewed"
        )
    notes += one_time_notes(t.name, t.times, t.absolute) + t.clock_notes
    if note := ring_order_note(t.name, t.elevations, t.ring_span):
        notes.append(note)
    if note := unread_time_note(t.name, t.untimed, clouds, t.time_like):
        notes.append(note)
    if t.unringed and t.unringed < clouds:
        notes.append(
            f"topic '{t.name}': {t.unringed} of {clouds} clouds have no ring field, the others "
            "have one (a driver relaunched with another layout?); their epochs' scans carry "
            "no rings"
        )
    return notes


def _point_notes(t: TopicIndex) -> list[str]:
    """A topic's notes on the points left out: "no ring" and stray ring ids, Livox noise."""
    notes = []
    if t.no_ring:
        notes.append(
            f"topic '{t.name}': {t.no_ring} points carry their ring field type's largest "
            'value (65535 in a uint16) as ring id, a driver\'s "no ring"?; left out'
        )
    if t.noise:
        notes.append(
            f"topic '{t.name}': {t.noise} points the Livox lidar marks as high confidence "
            "noise (its tag: rain, dust, a return on the window?); left out"
        )
    if t.ring_span is not None:
        notes.append(stray_note(t.name, t.ring_points, t.ring_span))
    return notes


def _stamped_back(index: BagIndex, k: int) -> str:
    """The note on topic ``k``'s messages stamped before the one recorded before them, or
    "". One publisher stamps its messages in order, so a stamp going back is a recording out
    of order (a short step), a clock reset (a sensor's own clock restarting, a simulated
    clock looping) or two publishers; read in stamp order, such an epoch lands among
    earlier ones."""
    stamps = index.sweep_stamp[(index.sweep_topic == k) & ~index.sweep_duplicate]
    step = np.diff(stamps)
    back = int(np.count_nonzero(step < 0))
    if not back:
        return ""
    return (
        f"{back} of {len(stamps)} messages are stamped before the one recorded before them "
        f"(up to {-step.min() / 1e9:.6g} s earlier: recorded out of order, a clock reset, or "
        "two publishers?); the epochs are in stamp order, not the recording's"
    )


def crowded_notes(index: BagIndex, members: list[np.ndarray], times: np.ndarray) -> list[str]:
    """Notes on epochs holding more sweeps of a topic than most of its epochs hold
    (``members``: each epoch's sweep rows; ``times`` (E,) the epoch times, s): two sweeps
    stamped within one epoch period, or a lidar faster than the epoch rate at times; their
    points are merged into that epoch, each sweep timed by its own stamp."""
    notes = []
    for k, t in enumerate(index.topics):
        counts = np.array([np.count_nonzero(index.sweep_topic[m] == k) for m in members])
        usual = int(np.median(counts)) if len(counts) else 0
        crowded = np.flatnonzero(counts > max(usual, 1))
        if not usual or not len(crowded):
            continue
        e = int(crowded[0])
        stamps = index.sweep_stamp[members[e][index.sweep_topic[members[e]] == k]]
        shown = ", ".join(f"{s // 10**9}.{s % 10**9:09d}" for s in np.sort(stamps)[:3].tolist())
        why = "stamped alike: a driver repeating a stamp, or parts of one sweep?"
        if len(np.unique(stamps)) == len(stamps):
            why = "stamped too close together, or a lidar faster than --epoch-rate?"
        notes.append(
            f"topic '{t.name}': {len(crowded)} epoch(s) hold more of its messages than the "
            f"{usual} most hold (first: epoch {e}, t = {times[e]:.3f} s, stamps {shown} s: "
            f"{why}); they are merged into the epoch, each placed by its own stamp"
        )
    return notes
