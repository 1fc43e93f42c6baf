"""The extraction of the epochs that seed the map (``extraction.ransac_unjudged: seed``).

The first epoch's planes become the map's landmarks before any other scan confirms them,
and the second epoch is registered against them alone, with the wide gates of a run that
has measured no motion yet: a level "plane" cut through several facades' scan lines there
holds the first steps' roll (lidar world 161 at 2 cm: 0.17 deg off, later steps
0.001-0.005). Later scans meet a map of many confirmed landmarks and gates from measured
deviations. ``seed`` refuses the RANSAC planes the agreement check cannot judge
(:func:`planodom.extraction.lidar.agreement.cutting_planes`) only in the extractions made
while the first :data:`SEED_EPOCHS` epochs are registered.
"""

from __future__ import annotations

from planodom.config import ExtractionConfig

#: The epochs whose extractions ``seed`` judges: the first (the map's seed, extracted
#: again when the second measures a twist) and the second (registered against it alone).
SEED_EPOCHS = 2


def seed_extraction(config: ExtractionConfig, registered: int) -> ExtractionConfig:
    """``config`` for an extraction made when ``registered`` epochs are registered: with
    ``ransac_unjudged: seed`` and fewer than :data:`SEED_EPOCHS` of them, the same with
    ``refused``; else ``config`` itself."""
    if config.ransac_unjudged != "seed" or registered >= SEED_EPOCHS:
        return config
    return config.model_copy(update={"ransac_unjudged": "refused"})
