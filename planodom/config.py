"""The one typed configuration of the planodom pipeline (pydantic, YAML in and out).

Every tunable threshold lives here with its unit in its name or docstring. Each stage owns
one section; ``PlanodomConfig`` nests them. Angles in configs are in degrees where the
field name says ``_deg``; everything else is SI.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from planodom.errors import ConfigError


class Section(BaseModel):
    """Base of every config section: unknown keys are errors, values are validated."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)


class ExtractionConfig(Section):
    """Plane extraction (planodom.extraction)."""


class AssociationConfig(Section):
    """Lenient and strict data association (planodom.association)."""


class OdometryConfig(Section):
    """Rotation / translation consensus and the divide-and-conquer pipeline."""


class SmoothingConfig(Section):
    """Factor-graph smoothing (planodom.smoothing)."""


class PlanodomConfig(Section):
    """All sections of the pipeline."""

    extraction: ExtractionConfig = ExtractionConfig()
    association: AssociationConfig = AssociationConfig()
    odometry: OdometryConfig = OdometryConfig()
    smoothing: SmoothingConfig = SmoothingConfig()

    @classmethod
    def from_yaml(cls, path: str | Path) -> PlanodomConfig:
        """Load a (partial) config; missing keys keep their defaults."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text()) or {}
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read config ({exc.strerror})") from exc
        except yaml.YAMLError as exc:
            raise ConfigError(f"{path}: not valid YAML ({exc})") from exc
        return cls.from_dict(data, source=str(path))

    @classmethod
    def from_dict(cls, data: dict, source: str = "config") -> PlanodomConfig:
        """Validate a nested dict; errors name the source and the field."""
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            first = exc.errors()[0]
            loc = ".".join(str(x) for x in first["loc"])
            raise ConfigError(f"{source}: field '{loc}': {first['msg']}") from exc

    def to_yaml(self, path: str | Path | None = None) -> str:
        """The resolved config as YAML text; also written to ``path`` when given."""
        text = yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False)
        if path is not None:
            Path(path).write_text(text)
        return text
