"""One calibration request, built once by the CLI, the API and the evaluation, validated once, stored with a
service job as it is and handed as it is to the worker; :func:`resolve` reads it against the dataset into the
numerical core's request (calib.methods.SolveRequest) with every decision it made and why.

The validated value types here (bounded, no NaN, unknown keys refused) are the service's request vocabulary
too (rigd.api.models).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator

from calib.assess import TrustOptions
from calib.errors import CalibError
from calib.geometry import Transform
from calib.methods import Method, SolveRequest
from calib.prior import Prior
from calib.search import default_search
from rigd.dataset import Dataset
from rigd.dataset.lasers import VLP16
from rigd.dataset.pcd import read_pcd
from rigd.dataset.records import (
    MODEL_ELEVATION_SIGMA_DEG,
    TOLERANCE_ROT_DEG,
    TOLERANCE_TRANS_CM,
    TOLERANCE_WHY,
    CameraConfig,
    CameraKind,
    lever_arm_problem,
    prior_from_yaml,
    tolerance_from_yaml,
)
from rigd.dataset.thin import ring_elevations_deg
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.errors import RigdError
from rigd.store.jsonsafe import unicode_safe

Coordinate = Annotated[float, Field(ge=-1e3, le=1e3)]
Angle = Annotated[float, Field(ge=-720.0, le=720.0)]
Vec3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Row4 = Annotated[list[Coordinate], Field(min_length=4, max_length=4)]


def _within(low: float, high: float, unit: str, why: str) -> Callable[[float], float]:
    """A check refusing values outside [low, high] with a message naming the range and why it is the range (the
    schema states it too, as minimum and maximum)."""
    def check(value: float) -> float:
        if not low <= value <= high:
            raise ValueError(f"must be within {low:g} .. {high:g} {unit}, got {value:g}: {why}")
        return value
    return check


def _range(low: float, high: float) -> Any:
    return Field(json_schema_extra={"minimum": low, "maximum": high})


# A tolerance or threshold per axis, within rig.yaml's bounds (rigd.dataset.records says why these).
ToleranceDeg = Annotated[float, _range(*TOLERANCE_ROT_DEG),
                         AfterValidator(_within(*TOLERANCE_ROT_DEG, "deg", TOLERANCE_WHY))]
ToleranceCm = Annotated[float, _range(*TOLERANCE_TRANS_CM),
                        AfterValidator(_within(*TOLERANCE_TRANS_CM, "cm", TOLERANCE_WHY))]
# A prior's sigma: how well the rig's drawing knows the lever arm or the mounting angles.
PriorSigmaCm = Annotated[float, _range(0.01, 1000.0), AfterValidator(_within(
    0.01, 1000.0, "cm", "no drawing knows a lever arm better than 0.1 mm, and 10 m is no prior at all"))]
PriorSigmaDeg = Annotated[float, _range(0.001, 180.0), AfterValidator(_within(
    0.001, 180.0, "deg", "no drawing knows a mounting angle better than 0.001 deg, and 180 deg is no prior at all"))]
# sigma_in of a coarse-to-fine level, deg at 1 m: narrower than half a working pixel (0.18 deg) it sees no edge.
SigmaIn = Annotated[float, _range(0.1, 30.0), AfterValidator(_within(
    0.1, 30.0, "deg", "a kernel narrower than half a working pixel (0.18 deg) sees no edge, wider than 30 deg no "
    "alignment"))]


MAX_NESTING = 16  # levels of objects and arrays in a request body; the deepest request needs 4


def body_problem(value: Any) -> str | None:
    """What makes a parsed JSON body unfit before validation, or None: nesting deeper than ``MAX_NESTING``, or
    a string or key holding a lone surrogate. Walked with a stack, not recursion: a 1 KB body can nest
    hundreds of levels deep."""
    stack: list[tuple[Any, str, int]] = [(value, "body", 0)]
    while stack:
        item, where, depth = stack.pop()
        if isinstance(item, str):
            if unicode_safe(item) != item:
                return (f"{where}: text must be Unicode, it holds a lone surrogate (a \\ud800-\\udfff escape "
                        "outside a pair)")
            continue
        if not isinstance(item, dict | list):
            continue
        if depth == MAX_NESTING:
            return (f"{where}: the body is nested more than {MAX_NESTING} levels deep (objects and arrays); "
                    "no request of this API needs that many")
        if isinstance(item, dict):  # a key is checked before its value
            children = [(part, f"{where}.{unicode_safe(str(k))}") for k, v in item.items() for part in (k, v)]
        else:
            children = [(v, f"{where}[{i}]") for i, v in enumerate(item)]
        stack.extend((child, at, depth + 1) for child, at in reversed(children))
    return None


class Request(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    @model_validator(mode="before")
    @classmethod
    def _fit(cls, data: Any) -> Any:
        # JSON's "\ud800" parses to a string no UTF-8 can carry: it could be neither stored nor answered. And
        # a deep body would exhaust the recursion of whatever walks it next (validation, the error's echo).
        problem = body_problem(data)
        if problem is not None:
            raise ValueError(problem)
        return data


class TransformIn(Request):
    """T_camera_lidar (p_cam = R p_lidar + t): a 4x4 ``matrix``, or ``rpy_deg`` (deg) with ``xyz_m`` (m)."""

    matrix: Annotated[list[Row4], Field(min_length=4, max_length=4)] | None = None
    rpy_deg: Annotated[list[Angle], Field(min_length=3, max_length=3)] | None = None
    xyz_m: Vec3 | None = None

    @model_validator(mode="after")
    def _valid(self) -> TransformIn:
        try:
            self._make()
        except CalibError as exc:
            raise ValueError(str(exc)) from exc
        return self

    def _make(self) -> Transform:
        if self.matrix is not None and self.rpy_deg is None and self.xyz_m is None:
            return Transform.from_matrix(np.asarray(self.matrix, dtype=np.float64))
        if self.matrix is None and self.rpy_deg is not None and self.xyz_m is not None:
            return Transform.from_rpy_xyz(np.asarray(self.rpy_deg, dtype=np.float64),
                                          np.asarray(self.xyz_m, dtype=np.float64))
        raise ValueError("give either matrix, or rpy_deg together with xyz_m")

    @property
    def transform(self) -> Transform:
        return self._make()

    @classmethod
    def of(cls, transform: Transform) -> TransformIn:
        """``transform`` as its matrix."""
        return cls(matrix=transform.matrix.tolist())


class PriorIn(Request):
    """A Gaussian prior per axis from the rig's drawing (rig.yaml's ``prior`` form): the lever arm ``xyz_m``
    (t of T_camera_lidar, m) with ``sigma_cm``, and/or the rotation ``rpy_deg`` with ``sigma_deg``."""

    xyz_m: Vec3 | None = None
    sigma_cm: PriorSigmaCm | None = None
    rpy_deg: Annotated[list[Angle], Field(min_length=3, max_length=3)] | None = None
    sigma_deg: PriorSigmaDeg | None = None

    @model_validator(mode="after")
    def _pairs(self) -> PriorIn:
        if (self.xyz_m is None) != (self.sigma_cm is None):
            raise ValueError("a lever-arm prior needs both xyz_m and sigma_cm")
        if self.xyz_m is not None and (problem := lever_arm_problem(self.xyz_m)) is not None:
            raise ValueError(problem)
        if (self.rpy_deg is None) != (self.sigma_deg is None):
            raise ValueError("a rotation prior needs both rpy_deg and sigma_deg")
        return self


class ToleranceIn(Request):
    """The field tolerance per axis: an axis is known when 2.5 sigma is within it (docs/trust.md)."""

    rotation_deg: ToleranceDeg = Field(default=0.2, description="per rotation axis, deg (0.001 .. 10)")
    translation_cm: ToleranceCm = Field(default=2.0, description="per translation axis, cm (0.01 .. 100)")
    rpy_deg: Annotated[list[ToleranceDeg], Field(min_length=3, max_length=3)] | None = Field(
        None, description="each rotation axis's own (roll, pitch, yaw about the LiDAR's x, y, z), deg")
    xyz_cm: Annotated[list[ToleranceCm], Field(min_length=3, max_length=3)] | None = Field(
        None, description="each translation axis's own (x, y, z), cm")




class Start(Enum):
    """Where a calibration starts."""

    RIG = "rig"  # the rig file's initial guess (the dataset's rig.yaml; the service's if it gives one); else search
    SEARCH = "search"  # the global search over the mounts (after a reassembly)
    GIVEN = "given"  # the transform in the request
    ACTIVE = "active"  # the service's active extrinsics version (the request carries it and its number)


class Options(Request):
    """What a calibration solves with: the same fields from `rigd calibrate`'s options, the service's body and
    the evaluation's settings. A new option is a field here plus the code that uses it (:func:`resolve`)."""

    method: Method | None = Field(None, description="the method; absent: the dataset's default, said in the report "
                                  "(the GMM; NID with its assessment on a single pinhole camera given a start)")
    prior: PriorIn | None = Field(None, description="Gaussian prior per axis; absent: the dataset's rig.yaml prior")
    fix_translation: bool = Field(False, description="hold the translation at the prior's lever arm (or the start's)")
    tolerance: ToleranceIn | None = Field(None, description="field tolerance of the verdict; absent: the dataset's "
                                          "rig.yaml tolerance, else 0.2 deg / 2 cm")
    fit_elevation_offset: bool = Field(False, description="also fit the LiDAR's common elevation offset, for "
                                       "cameras that look all round (a panorama or a head); about 1.5 times the time")
    sigmas_deg: Annotated[list[SigmaIn], Field(min_length=1, max_length=6)] | None = Field(
        None, description="sigma_in per coarse-to-fine level of a GMM method, deg at 1 m; absent: the method's own "
        "schedule (the levels used are in the version's quality figures)")


class CalibrationRequest(Request):
    """One calibration of a dataset: where it starts, the :class:`Options`, and how the job runs (``out_dir``
    None: nothing is written, as for an evaluation's runs; ``assess`` False: no restarts, uncertainty or
    verdict)."""

    dataset: Path
    start: Start = Start.RIG
    initial: TransformIn | None = None  # the transform of Start.GIVEN and Start.ACTIVE (and a service rig's guess)
    start_version: int | None = None  # Start.ACTIVE: the version it is
    options: Options = Options()
    out_dir: Path | None = None
    write_visuals: bool = True
    workers: Annotated[int, Field(ge=1, le=64)] = 2  # processes: the pairs' edges and the independent solves
    max_width: Annotated[int, Field(ge=1)] | None = WORKING_WIDTH_PX  # px: wider images halved on load; None: as is
    assess: bool = True

    @model_validator(mode="after")
    def _start(self) -> CalibrationRequest:
        if self.start in (Start.GIVEN, Start.ACTIVE) and self.initial is None:
            raise ValueError(f"start {self.start.value} needs the initial transform")
        if self.start is Start.SEARCH and self.initial is not None:
            raise ValueError("start search takes no initial transform")
        return self


@dataclass(frozen=True)
class Decision:
    """What :func:`resolve` chose where the request left it open, and why, in words the report and CLI give."""

    choice: str
    why: str


@dataclass(frozen=True)
class Resolved:
    """A request read against its dataset: the numerical core's request, and the start and method chosen."""

    solve: SolveRequest
    start: Start
    start_why: Decision
    method_why: Decision
    start_version: int | None = None  # Start.ACTIVE: the version it started from


def _start(request: CalibrationRequest, dataset: Dataset) -> tuple[Transform | None, Start, Decision]:
    if request.start is Start.SEARCH:
        return None, Start.SEARCH, Decision("global search", "asked for (after a reassembly)")
    if request.start is Start.GIVEN:
        assert request.initial is not None
        return request.initial.transform, Start.GIVEN, Decision("the transform given", "asked for")
    if request.start is Start.ACTIVE:
        assert request.initial is not None
        return request.initial.transform, Start.ACTIVE, Decision(f"active version {request.start_version}",
                                                                 "asked for")
    guess = request.initial.transform if request.initial is not None else dataset.rig.initial_guess
    if guess is None:
        return None, Start.SEARCH, Decision("global search", "the rig file has no initial guess")
    return guess, Start.RIG, Decision("the rig file's initial guess", "asked for")


def _method(options: Options, dataset: Dataset, initial: Transform | None, prior: Prior | None) -> Decision:
    """The method's name and why: as asked, else NID with its assessment on a single pinhole camera, where on
    real frames the GMM's finest cost has no minimum near the reference and NID's has (docs/baselines.md), when
    NID can run; elsewhere the GMM."""
    if options.method is not None:
        return Decision(options.method.value, "asked for")
    camera = dataset.source_camera
    if not (isinstance(camera, CameraConfig) and camera.kind is CameraKind.PINHOLE):
        kind = dataset.rig.camera.kind.value
        return Decision(Method.GMM.value, f"the default for {'an' if kind[0] in 'aeiou' else 'a'} {kind} camera")
    why_not = ("this calibration searches for its start, which scores the GMM's edges" if initial is None
               else "a Gaussian prior is given, which NID's cost cannot weigh" if prior is not None and prior.active
               else None if _has_intensity(dataset) else "the clouds carry no intensity to compare with the image")
    if why_not is not None:
        return Decision(Method.GMM.value, f"NID is the default on one pinhole camera, but {why_not}")
    return Decision(Method.NID_ASSESSED.value, "the default on one pinhole camera, where NID's cost has its minimum "
                    "near the reference and the GMM's finest may not (docs/baselines.md)")


def _has_intensity(dataset: Dataset) -> bool:
    intensity = dataset.load_pair(0).cloud.intensity if len(dataset) else None
    return intensity is not None and bool(np.ptp(intensity) > 0)  # a field of one value (some drivers write 0)


def _prior(options: Options, dataset: Dataset) -> Prior | None:
    given = options.prior.model_dump(exclude_none=True) if options.prior is not None else None
    prior = prior_from_yaml(given, "request prior") if given else dataset.rig.prior
    if not options.fix_translation:
        return prior
    return Prior(fix_translation=True) if prior is None else replace(prior, fix_translation=True)


def _trust(request: CalibrationRequest, dataset: Dataset) -> TrustOptions | None:
    """The assessment's options: the request's tolerance, else rig.yaml's, with rig.yaml's declared sensor
    uncertainties (:func:`with_camera_model`); None when the request is not assessed."""
    if not request.assess:
        return None
    tolerance = request.options.tolerance
    trust = (tolerance_from_yaml(tolerance.model_dump(exclude_none=True), "request tolerance") if tolerance is not None
             else dataset.rig.tolerance or TrustOptions())
    return with_camera_model(trust, dataset)


SPARSE_RINGS_DEG = 1.0  # median spacing of neighbouring rings from which a LiDAR is as sparse as a VLP-16 (2 deg)


def elevation_sigma_deg(dataset: Dataset) -> float:
    """The sigma of the LiDAR's common elevation error the assessment takes, deg: rig.yaml's, else the LiDAR
    model's (rigd.dataset.records.MODEL_ELEVATION_SIGMA_DEG), else for rings as sparse as a VLP-16's (at least
    SPARSE_RINGS_DEG apart) the VLP-16's: a common error of a sparse LiDAR's beams leaks into the tilt and z by
    which rings cross which edges (docs/trust.md); a dense one's clouds hold it to far less."""
    rig = dataset.rig
    if rig.lidar_elevation_sigma_declared_deg is not None or rig.lidar_elevation_sigma_deg or not len(dataset):
        return rig.lidar_elevation_sigma_deg
    cloud = read_pcd(dataset.pair_dirs[0] / "cloud.pcd")
    if cloud.ring is None:
        return 0.0
    rings = sorted(ring_elevations_deg(cloud).values())
    sparse = len(rings) > 1 and float(np.median(np.diff(rings))) >= SPARSE_RINGS_DEG
    return MODEL_ELEVATION_SIGMA_DEG[VLP16] if sparse else 0.0


def with_camera_model(trust: TrustOptions, dataset: Dataset) -> TrustOptions:
    """``trust`` with the sensors' uncertainties: the LiDAR's elevation offset sigma (:func:`elevation_sigma_deg`),
    and a single camera's principal-point sigma as rotations (at the size on disk; a head's and a panorama's stay
    K-exact)."""
    if sigma := elevation_sigma_deg(dataset):
        trust = replace(trust, elevation_sigma_deg=sigma)
    camera = dataset.source_camera
    if not isinstance(camera, CameraConfig):
        return trust
    return replace(trust, intrinsics_sigma_rad=camera.intrinsics_sigma_rad())


def _check_elevation_fit(options: Options, dataset: Dataset) -> None:
    """The elevation offset is fitted only where cameras look all round: one camera cannot tell it from a tilt."""
    kind = dataset.rig.camera.kind
    if options.fit_elevation_offset and kind not in (CameraKind.EQUIRECTANGULAR, CameraKind.HEAD):
        raise RigdError(f"{dataset.root}: fitting the LiDAR's elevation offset needs cameras that look all round (a "
                        f"panorama or a head); one {kind.value} camera cannot tell it from a tilt: declare it in "
                        "rig.yaml instead (lidar: {elevation_offset_deg: ..., elevation_offset_sigma_deg: ...})")


def resolve(request: CalibrationRequest, dataset: Dataset) -> Resolved:
    """``request`` read against ``dataset`` (its rig.yaml's guess, prior, tolerance, search range and declared
    sensor uncertainties where the request gives none); RigdError naming what the method cannot do."""
    if len(dataset) == 0:
        raise RigdError(f"{dataset.root}: dataset has no pairs (pairs/NNNN)")
    options = request.options
    _check_elevation_fit(options, dataset)
    initial, start, start_why = _start(request, dataset)
    prior = _prior(options, dataset)
    method_why = _method(options, dataset, initial, prior)
    solve = SolveRequest(
        method=Method(method_why.choice), initial=initial, prior=prior, trust=_trust(request, dataset),
        sigmas_deg=None if options.sigmas_deg is None else tuple(options.sigmas_deg),
        search=dataset.rig.search or default_search(dataset.rig.camera.models()[0]),
        fit_elevation=options.fit_elevation_offset)
    try:
        solve.check()
    except CalibError as exc:
        raise RigdError(f"{dataset.root}: {exc}") from exc
    return Resolved(solve, start, start_why, method_why, request.start_version if start is Start.ACTIVE else None)
