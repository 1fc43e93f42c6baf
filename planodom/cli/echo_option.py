"""The ``--echo`` option of ``run``, ``smooth`` and ``convert``: the returns read of each
beam of a bag's ``sensor_msgs/MultiEchoLaserScan`` (``BagOptions.echo``)."""

from __future__ import annotations

from typing import Annotated

import typer

Echo = Annotated[
    str,
    typer.Option(
        "--echo",
        help="Bags: the echoes read of each beam of a MultiEchoLaserScan: first (the "
        "nearest return, default), last, strongest (by intensity) or all.",
    ),
]
