"""The dataset format: a directory of scans, optional ground truth and rig description.

Layout::

    <dataset>/
        scans/000000.ply, 000001.ply, ...   one file per epoch, in time order
        poses.tum                           optional: ground truth T_world_base per epoch
        times.txt                           optional: reference time per epoch (no poses.tum)
        rig.yaml                            optional: the rig (:class:`planodom.rig.Rig`)

- Scan files hold the points of one epoch in the vehicle base frame at each point's
  acquisition time: PLY vertices ``x y z`` (float32 or float64, metres), optional ``ring``
  (int32 scan-line id), ``t`` (float64 s relative to the epoch's reference time) and, for
  simulated data, ``label`` (int32 true surface id). ``.pcd`` files with the same fields
  and raw ``.bin`` files (float32 ``x y z intensity`` rows as KITTI's, or ``x y z
  intensity ring`` as nuScenes', :mod:`planodom.datasets.bin_scan`) are read too; all
  files of a dataset share one extension. Point times may be absolute (Unix) times, and
  multi-return clouds keep one return per firing (:mod:`planodom.datasets.scan_io`); ring
  ids in a lidar's firing order are given to its rings in elevation order, noted
  (:mod:`planodom.datasets.folder_ring_order`). A directory of scan files can be given
  directly instead of a dataset with a ``scans/`` folder.
- ``poses.tum``: ``time tx ty tz qx qy qz qw`` per epoch, ``T_world_base`` at the epoch's
  reference time (the TUM format of evo).
- ``times.txt``: one reference time per epoch (seconds, one number per line, strictly
  increasing; ``#`` comments and blank lines skipped), for a dataset without ground
  truth, e.g. one converted from a bag without a reference (seconds since the Unix epoch,
  the bag's clock). :func:`write_dataset` writes it whenever it writes no ``poses.tum``.
- Epoch times come from ``poses.tum`` when present, else from ``times.txt``, else from
  KITTI raw's ``timestamps.txt`` beside a ``data/`` folder of scans, else from the scan
  file names when they are the clouds' Unix stamps (``SEC.NSEC.pcd``, ``SEC_NSEC.pcd``,
  integer ns, as tools name a bag's clouds: :mod:`planodom.datasets.scan_names`), else
  ``k / epoch_rate`` with ``epoch_rate`` (Hz) from ``rig.yaml``, else ``k * 0.1`` s.
  Without either file, a gap in numbered scan files (``000001``, ``000003``) is an
  error, not a guess: the epochs around it would be taken as consecutive.
- ``rig.yaml`` is read and validated once, into ``Dataset.rig`` (a typed
  :class:`planodom.rig.Rig`: epoch rate, sensor origins per ring, motion bounds,
  extrinsics, platform); keys it does not interpret (for simulated data the sensor models, the
  scene and the seed) are kept in ``Rig.extra``.

Every problem with a dataset raises :class:`planodom.errors.DatasetError` naming the file.
"""

from planodom.datasets.dataset import (
    DEFAULT_EPOCH_PERIOD,
    Dataset,
    epoch_times,
    load_dataset,
    read_rig,
    read_times,
    write_dataset,
    write_rig,
    write_times,
)
from planodom.datasets.scan_io import SCAN_EXTENSIONS, read_scan, write_scan
from planodom.datasets.tum import read_tum, write_tum

__all__ = [
    "DEFAULT_EPOCH_PERIOD",
    "SCAN_EXTENSIONS",
    "Dataset",
    "epoch_times",
    "load_dataset",
    "read_rig",
    "read_scan",
    "read_times",
    "read_tum",
    "write_dataset",
    "write_rig",
    "write_scan",
    "write_times",
    "write_tum",
]
