"""The one typed configuration of the planodom pipeline (pydantic, YAML in and out).

Every tunable threshold lives here with its unit in its name or docstring. Each stage owns
one section; ``PlanodomConfig`` nests them. Angles in configs are in degrees where the
field name says ``_deg``; everything else is SI.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError, model_validator

from planodom.config.association import AssociationConfig
from planodom.config.extraction import ExtractionConfig
from planodom.config.odometry import OdometryConfig
from planodom.config.planemap import PlanemapConfig
from planodom.config.section import Section, one_line
from planodom.config.smoothing import SmoothingConfig
from planodom.config.sweep_refine import SweepRefineConfig
from planodom.errors import ConfigError
from planodom.yaml_files import read_yaml_file

__all__ = [
    "AssociationConfig",
    "ExtractionConfig",
    "OdometryConfig",
    "PlanemapConfig",
    "PlanodomConfig",
    "Section",
    "SmoothingConfig",
    "SweepRefineConfig",
]


class PlanodomConfig(Section):
    """All sections of the pipeline: ``extraction``, ``association``, ``odometry``,
    ``smoothing`` (one typed, range-checked section each; SI units unless a field says
    ``_deg``). ``PlanodomConfig.from_yaml(path)`` reads any subset over the defaults,
    ``updated({"section.field": value})`` derives a changed copy, ``to_yaml()`` writes it.
    """

    extraction: ExtractionConfig = ExtractionConfig()
    association: AssociationConfig = AssociationConfig()
    odometry: OdometryConfig = OdometryConfig()
    planemap: PlanemapConfig = PlanemapConfig()
    smoothing: SmoothingConfig = SmoothingConfig()
    sweep_refine: SweepRefineConfig = SweepRefineConfig()

    @model_validator(mode="before")
    @classmethod
    def _planes_for_smoothing(cls, data: Any) -> Any:
        """The deskew-noise modes that read each plane's deskewing Jacobian
        (``smoothing.deskew_noise: twist_change_jacobian[_net]``,
        ``smoothing.covariance_model: sandwich``, ``planemap.deskew_variance:
        twist_change`` and ``lead_weights: stated``, ``odometry.plane_deskew_noise`` and
        ``stated_deskew_noise`` not off, ``odometry.deskew_pass_skip: planes``) switch on
        its computation in the extraction (``extraction.deskew_jacobian``);
        ``planemap.twist_estimation`` other than ``none`` and ``lead_weights: unknown``
        switch on the planes' time moments
        (``extraction.time_moments``). The default
        covariance model, "auto", leaves it off here: the batch smoothing switches it on for
        the odometry it runs (:func:`planodom.smoothing.run.smoothing_config`), so that a
        run without smoothing does not pay for it."""
        if not isinstance(data, Mapping):
            return data
        smoothing = data.get("smoothing")
        mode = getattr(smoothing, "deskew_noise", None)
        if isinstance(smoothing, Mapping):
            mode = smoothing.get("deskew_noise")
        planemap = data.get("planemap")
        deskew = getattr(planemap, "deskew_variance", None)
        lead = getattr(planemap, "lead_weights", None)
        if isinstance(planemap, Mapping):
            deskew = planemap.get("deskew_variance")
            lead = planemap.get("lead_weights")
        twist = getattr(planemap, "twist_estimation", None)
        if isinstance(planemap, Mapping):
            twist = planemap.get("twist_estimation")
        model = getattr(smoothing, "covariance_model", None)
        if isinstance(smoothing, Mapping):
            model = smoothing.get("covariance_model")
        odometry = data.get("odometry")
        planes = getattr(odometry, "plane_deskew_noise", None)
        stated = getattr(odometry, "stated_deskew_noise", None)
        skip = getattr(odometry, "deskew_pass_skip", None)
        if isinstance(odometry, Mapping):
            planes = odometry.get("plane_deskew_noise")
            stated = odometry.get("stated_deskew_noise")
            skip = odometry.get("deskew_pass_skip")
        wanted = isinstance(mode, str) and mode.startswith("twist_change_jacobian")
        wanted = wanted or model == "sandwich" or planes in ("twist", "change")
        wanted = wanted or stated == "shared" or skip == "planes"
        moments = (isinstance(twist, str) and twist != "none") or lead == "unknown"
        wanted = wanted or deskew == "twist_change" or lead == "stated"
        if not (wanted or moments):
            return data
        extraction = data.get("extraction", {})
        if isinstance(extraction, ExtractionConfig):
            extraction = extraction.model_dump()
        if not isinstance(extraction, Mapping):
            return data  # the section's own validation reports it
        switched = {"time_moments": True} if moments else {}
        if wanted:
            switched["deskew_jacobian"] = True
        # a value that is not a bool stays, for the section's validation to name it
        switched = {k: v for k, v in switched.items() if isinstance(extraction.get(k, v), bool)}
        return {**data, "extraction": {**extraction, **switched}}

    @model_validator(mode="after")
    def _stated_once(self) -> PlanodomConfig:
        """The steps' deskewing error in one place: ``odometry.stated_deskew_noise`` puts it
        in their stated covariances, ``smoothing.sandwich_relative_ends: both`` in the
        sandwich; both would count it twice."""
        if self.odometry.stated_deskew_noise != "off" and (
            self.smoothing.sandwich_relative_ends == "both"
        ):
            raise ConfigError(
                "odometry.stated_deskew_noise: shared and smoothing.sandwich_relative_ends: "
                "both model the same deskewing error of the steps; set one of them off/none"
            )
        return self

    @classmethod
    def from_yaml(cls, path: str | Path) -> PlanodomConfig:
        """Load a (partial) config; missing keys keep their defaults."""
        path = Path(path)
        data = read_yaml_file(path, "config", ConfigError) or {}
        return cls.from_dict(_empty_sections(data, cls), source=str(path))

    @classmethod
    def from_dict(cls, data: dict, source: str = "config") -> PlanodomConfig:
        """Validate a nested dict; errors name the source and the field."""
        if not isinstance(data, Mapping):
            raise ConfigError(
                f"{source}: a config holds a mapping of sections, not {type(data).__name__}"
            )
        if _another_file(data, list(cls.model_fields)):
            raise ConfigError(_no_section(source, [str(k) for k in data], list(cls.model_fields)))
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            raise ConfigError(one_line(exc, source, cls)) from None
        except ConfigError as exc:  # raised by a section's own cross-field checks
            raise ConfigError(f"{source}: {exc}") from exc

    def updated(self, changes: Mapping[str, object], source: str = "config") -> PlanodomConfig:
        """A new config with ``changes`` applied and every check run again.

        The one way to derive a changed config (CLI options, experiments, the streaming
        odometry's widened bounds): ``changes`` maps dotted field names to values, e.g.
        ``{"association.max_translation_m": 2.0, "extraction.time_windows.span_s": 0.02}``;
        the result is validated like a loaded file (``model_copy`` would skip that).
        The fields set explicitly (pydantic's ``model_fields_set``: read from a file, given
        in code or changed here) stay so, the others stay defaults that a dataset's
        platform may change (:mod:`planodom.odometry.platform`).
        Raises :class:`ConfigError` naming ``source`` and the field.
        """
        data = self.model_dump(mode="python")
        for dotted, value in changes.items():
            *path, name = dotted.split(".")
            node: Any = data
            for key in path:
                node = node.get(key) if isinstance(node, dict) else None
            if not path or not isinstance(node, dict) or name not in node:
                raise ConfigError(f"{source}: unknown config field {dotted!r}")
            node[name] = value
        new = type(self).from_dict(data, source=source)
        _keep_fields_set(new, self, [tuple(dotted.split(".")) for dotted in changes])
        return new

    def updated_fields(
        self, changes: Mapping[str, object], source: str = "config"
    ) -> PlanodomConfig:
        """:meth:`updated` by field assignment, for a caller that derives many configs (the
        loop closure's association bounds, one per attempt: 3 600 on a 2 000-epoch run,
        where revalidating the whole config took 1 ms each).

        Each changed field is checked as :meth:`updated` checks it (its section's field
        validation, run on assignment); the unchanged sections are shared with this
        config, not copied. The one check across sections (the extraction switched on by
        the smoothing's and the plane map's modes) reads ``extraction``, ``planemap`` and
        ``smoothing``: changes there go through :meth:`updated`.
        """
        by_section: dict[str, dict[str, object]] = {}
        for dotted, value in changes.items():
            section, _, name = dotted.partition(".")
            if section in {"extraction", "planemap", "smoothing"} or "." in name:
                return self.updated(changes, source)
            by_section.setdefault(section, {})[name] = value
        sections: dict[str, Section] = {}
        for section, fields in by_section.items():
            current = getattr(self, section, None)
            if not isinstance(current, Section):
                raise ConfigError(f"{source}: unknown config section {section!r}")
            copy = current.model_copy()
            for name, value in fields.items():
                if name not in type(current).model_fields:
                    raise ConfigError(f"{source}: unknown config field {section}.{name!r}")
                try:
                    setattr(copy, name, value)
                except ConfigError as exc:
                    raise ConfigError(f"{source}: {exc}") from exc
            sections[section] = copy
        return self.model_copy(update=sections)

    def to_yaml(self, path: str | Path | None = None) -> str:
        """The resolved config as YAML text; also written to ``path`` when given."""
        text = yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False)
        if path is not None:
            Path(path).write_text(text)
        return text


#: Top-level keys of a dataset's ``rig.yaml`` (:mod:`planodom.rig`), given as a config.
_RIG_FILE_KEYS = frozenset({"epoch_rate", "sensor_origins", "motion_bounds", "extrinsics"})


def _another_file(data: Mapping, sections: list[str]) -> bool:
    """Whether none of ``data``'s keys names a section, nor is a dotted field name, and
    either some are a ``rig.yaml``'s or there are several and none misspells a section (a
    misspelt or unknown section alone gets its own hint, :func:`.section.one_line`)."""
    keys = [str(k).partition(".")[0].lower() for k in data]
    if not keys or set(keys) & set(sections):
        return False
    near = [k for k in keys if difflib.get_close_matches(k, sections, n=1, cutoff=0.6)]
    return bool(_RIG_FILE_KEYS & set(keys)) or (len(keys) > 1 and not near)


def _no_section(source: str, keys: list[str], sections: list[str]) -> str:
    """The error for a mapping without any config section (another YAML or JSON file): its
    keys and the sections, and where a dataset's ``rig.yaml`` (the likeliest) belongs."""
    shown = ", ".join(keys[:4]) + (" ..." if len(keys) > 4 else "")
    rig = (
        ": a dataset's rig.yaml, which is read from the dataset folder"
        if _RIG_FILE_KEYS & set(keys)
        else ""
    )
    return (
        f"{source}: not a planodom config: its keys ({shown}) are none of the config's "
        f"sections ({', '.join(sections)}){rig}"
    )


def _keep_fields_set(new: BaseModel, old: BaseModel, changed: list[tuple[str, ...]]) -> None:
    """Mark in ``new`` (validated from ``old``'s whole dump with ``changed`` applied, which
    marks every field as set) only the fields ``old`` had set and the ``changed`` ones
    (dotted paths split), in nested sections too; a section replaced whole keeps what its
    validation set."""
    mine = {path[0] for path in changed}
    object.__setattr__(new, "__pydantic_fields_set__", set(old.model_fields_set) | mine)
    for name in type(new).model_fields:
        inner, before = getattr(new, name), getattr(old, name, None)
        same = isinstance(inner, BaseModel) and isinstance(before, type(inner))
        if same and before is not None and (name,) not in changed:
            _keep_fields_set(inner, before, [p[1:] for p in changed if p[0] == name])


def _empty_sections(data: Any, model: type[BaseModel]) -> Any:
    """``data`` with a section left empty in the file (``odometry:`` above keys all
    commented out: YAML's null, refused before as "Input should be a valid dictionary")
    read as no changes to it, as an empty file is; nested sections likewise."""
    if not isinstance(data, Mapping):
        return data
    out = dict(data)
    for key, value in data.items():
        field = model.model_fields.get(key) if isinstance(key, str) else None
        kind = None if field is None else field.annotation
        if not (isinstance(kind, type) and issubclass(kind, BaseModel)):
            continue
        out[key] = {} if value is None else _empty_sections(value, kind)
    return out
