"""kinecal — kinematic calibration of parallel and serial manipulators, from Python.

A thin layer over the kinecal Rust library (the same calls the ``kinecal`` command line makes):

>>> import kinecal
>>> model = kinecal.Model.load("irb120")                 # or a model file path
>>> truth, data = kinecal.simulate(model, 60, noise_mm=0.02, noise_deg=0.01, seed=7)
>>> cal = kinecal.calibrate(model, data, noise_mm=0.02, noise_deg=0.01)
>>> cal.verdict
'calibrated'

Units are millimetres and radians (``Data.read`` converts a file's own units); poses are 4×4
homogeneous matrices in mm. Errors raise :class:`KinecalError` (a ``ValueError``) carrying the
message the command line prints.
"""
from __future__ import annotations

import html
import json
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import _kinecal
from ._kinecal import Data, KinecalError, Model, __version__

__all__ = [
    "assess_circle",
    "plan_iso9283",
    "Model",
    "Data",
    "Calibration",
    "Update",
    "check",
    "plan_check",
    "Validation",
    "KinecalError",
    "calibrate",
    "validate",
    "validate_instrument",
    "predict_accuracy",
    "identifiability",
    "assess",
    "compensate",
    "filter_program",
    "simulate",
    "plan",
    "plan_sampled",
    "plan_instrument",
    "simulate_touches",
    "plan_touches",
    "SampledPlan",
    "__version__",
]


class Calibration:
    """The result of :func:`calibrate`: the calibrated model, the parameter table, the error
    statistics before and after, the verdict and the full report (``report``, the same document
    ``kinecal identify --json`` prints)."""

    def __init__(self, raw: Any) -> None:
        self._raw = raw
        self._report: Optional[Dict[str, Any]] = None

    @property
    def report(self) -> Dict[str, Any]:
        """The report as a dict (the document ``kinecal identify --json`` prints), built on first use."""
        if self._report is None:
            self._report = json.loads(self._raw.report_json())
        return self._report

    @property
    def model(self) -> Model:
        """The calibrated model (save it with ``open(path, "w").write(cal.model.to_toml())``)."""
        return self._raw.model

    @property
    def verdict(self) -> str:
        """``"calibrated"``, ``"usable-with-warnings"`` or ``"failed"``."""
        return self.report["verdict"]["status"]

    @property
    def reasons(self) -> List[str]:
        """Why the verdict is not ``"calibrated"`` (empty when it is)."""
        return list(self.report["verdict"]["reasons"])

    @property
    def converged(self) -> bool:
        return bool(self.report["converged"])

    @property
    def iterations(self) -> int:
        return int(self.report["iterations"])

    @property
    def sigma0(self) -> float:
        """A-posteriori standard deviation of unit weight (≈ 1 when the stated noise fits)."""
        return float(self.report["sigma0"])

    @property
    def parameters(self) -> List[Dict[str, Any]]:
        """One dict per parameter: name, group, unit, value, std_dev, status."""
        return list(self.report["params"])

    @property
    def identification(self) -> Dict[str, Any]:
        """Error statistics of the identification set after calibration (mm, deg)."""
        return dict(self.report["identification"]["after_stats"])

    @property
    def validation(self) -> Optional[Dict[str, Any]]:
        """Error statistics of the validation set after calibration (mm, deg), if one was given."""
        v = self.report.get("validation")
        return None if v is None else dict(v["after_stats"])

    @property
    def held_out(self) -> Optional[Dict[str, Any]]:
        """A validation set of instrument rows (seats, pivots, touches: held-out placements with
        artifacts of their own, each placed by its own rows with the model fixed), if one was
        given: ``rows``, ``before_rms_mm`` / ``after_rms_mm`` (nominal / calibrated, every row),
        and ``nominal`` / ``calibrated``, each what :func:`validate_instrument` returns (mm)."""
        h = self.report.get("held_out")
        return None if h is None else dict(h)

    @property
    def blunders(self) -> List[int]:
        """Ids of the poses set aside as gross blunders."""
        return list(self._raw.blunders)

    def report_html(self) -> str:
        """The report as one self-contained HTML page."""
        return self._raw.report_html()

    def _repr_html_(self) -> str:
        """The report inline in a notebook: the self-contained page in an ``iframe`` (its styles
        and its 3-D view's script stay inside it and run in a trusted or untrusted notebook)."""
        page = html.escape(self.report_html(), quote=True)
        return f'<iframe srcdoc="{page}" style="width:100%;height:820px;border:1px solid #ddd"></iframe>'

    def __repr__(self) -> str:
        v, h = self.validation, self.held_out
        if v:
            held = f", held-out RMS {v['position_rms_mm']:.4f} mm"
        elif h:
            held = f", held-out placements {h['before_rms_mm']:.4f} → {h['after_rms_mm']:.4f} mm RMS"
        else:
            held = ""
        return f"Calibration({self.report['model']!r}: {self.verdict}, σ̂₀ {self.sigma0:.3f}{held})"


class Validation:
    """Per-pose errors of a model on a data set and their statistics."""

    def __init__(self, stats: str, position: np.ndarray, orientation: Optional[np.ndarray]) -> None:
        #: Statistics (mm, deg): poses, position_mean_mm, position_rms_mm, position_max_mm, …
        self.stats: Dict[str, Any] = json.loads(stats)
        #: Position error of each pose (mm).
        self.position: np.ndarray = position
        #: Orientation error of each pose (rad), None for position data.
        self.orientation: Optional[np.ndarray] = orientation

    def __repr__(self) -> str:
        s = self.stats
        return f"Validation({s['poses']} poses: position RMS {s['position_rms_mm']:.4f} / max {s['position_max_mm']:.4f} mm)"


def calibrate(
    model: Model,
    data: Data,
    validation: Optional[Data] = None,
    *,
    noise_mm: Optional[float] = None,
    noise_deg: Optional[float] = None,
    encoder_noise_deg: Optional[float] = None,
    encoder_noise_mm: Optional[float] = None,
    method: str = "gauss-newton",
    frames: str = "estimate",
    reflectors: str = "frame",
    starts: int = 3,
    seed: int = 1,
    reweight: bool = False,
    huber: float = 5.0,
    seat_distances: Sequence[str] = (),
    kind_noise: Sequence[str] = (),
    validation_seat_distances: Sequence[str] = (),
    prior: Optional[Any] = None,
    false_alarm: float = 0.01,
) -> Any:
    """Identify the model's free parameters from ``data`` — the call behind ``kinecal identify``,
    with the same options: the measurement and tool frames found from the data (``frames=
    "estimate"``) or taken from the model (``"model"``), Gauss–Newton to convergence from
    ``starts`` starts, noise weights (``noise_mm``, ``noise_deg``; default: the model file's, else
    0.02 mm / 0.02°; ``encoder_noise_deg`` / ``encoder_noise_mm`` for the readings of observed
    joints, ``Model.observed``: default 0.01° / 0.01 mm), Huber loss (``huber`` robust σ, 0 = plain least squares), ``reflectors=
    "points"`` to fit three reflector centres; for seat data (a ``seat`` column), known distances
    between seats as ``"A:B:MM"`` strings (``seat_distances``, docs/instruments.md); each
    instrument kind's own noise as ``"KIND=MM"`` strings (``kind_noise``, e.g. ``"probe=0.005"``,
    ``"seat=0.01"``, ``"distance=0.001"``; a kind without its own takes ``noise_mm``). Instrument
    rows in ``validation`` are held-out placements with artifacts of their own (``Calibration.
    held_out``); ``validation_seat_distances`` (``"A:B:MM"``, that file's seat numbers) are the
    known distances between their seats.

    With ``prior`` (a :class:`Calibration`, or a :class:`Model` loaded from a calibrated model
    file): the prior's parameters and covariance as information and ``data`` (a few new poses) as
    data, as ``kinecal identify --prior`` does; the patterns the new poses contradict the prior
    along are released, each tested at ``false_alarm``. Returns an :class:`Update` then."""
    if prior is not None:
        raw = prior._raw if isinstance(prior, Calibration) else prior
        return Update(_kinecal.update(raw, data, false_alarm=false_alarm))
    return Calibration(
        _kinecal.calibrate(
            model,
            data,
            validation,
            noise_mm=noise_mm,
            noise_deg=noise_deg,
            encoder_noise_deg=encoder_noise_deg,
            encoder_noise_mm=encoder_noise_mm,
            method=method,
            frames=frames,
            reflectors=reflectors,
            starts=starts,
            seed=seed,
            reweight=reweight,
            huber=huber,
            seat_distances=list(seat_distances),
            kind_noise=list(kind_noise),
            validation_seat_distances=list(validation_seat_distances),
        )
    )


class Update:
    """The result of :func:`calibrate` with a ``prior``: the updated model and what moved."""

    def __init__(self, raw: Any) -> None:
        self._raw = raw
        self.report: Dict[str, Any] = json.loads(raw.report_json())

    @property
    def model(self) -> Model:
        """The updated model."""
        return self._raw.model

    @property
    def released(self) -> List[Dict[str, Any]]:
        """The patterns released (name, kind, fitted values)."""
        return self.report["released"]

    @property
    def moved(self) -> List[Dict[str, Any]]:
        """The parameters moved beyond their prior σ (name, unit, change, σ before and after)."""
        return self.report["moved"]

    @property
    def passed(self) -> bool:
        """The new poses and the updated calibration agree within noise."""
        return bool(self.report["passed"])

    @property
    def set_aside(self) -> Optional[Dict[str, Any]]:
        """The new pose set aside (its index among the new poses, position error in mm, χ² and
        rows), when the others agree without it and not with it: measure it again; else None."""
        return self.report["set_aside"]


def check(calibration: Any, data: Data, *, false_alarm: float = 0.01) -> Dict[str, Any]:
    """Re-measured poses ``data`` judged against the prediction of ``calibration`` (a
    :class:`Calibration`, or a :class:`Model` loaded from a calibrated model file), as ``kinecal
    check`` does: ``result["drifted"]``, the statistic and its bound, the pattern whose drop is
    furthest beyond its own bound (``result["pattern_test"]``), each pose, the pattern that
    fits best (``result["pattern"]``), and the one pose a disagreement rests on when the others
    agree (``result["one_pose"]``: then not drifted; measure that pose again)."""
    raw = calibration._raw if isinstance(calibration, Calibration) else calibration
    return json.loads(_kinecal.check(raw, data, false_alarm=false_alarm))


def plan_check(
    calibration: Any, configurations: np.ndarray, *, n: int = 5, drift_mm: float = 0.1, observe: str = "pose"
) -> Dict[str, Any]:
    """The ``n`` rows of ``configurations`` (candidates, (m, inputs) in rad / mm) at which a check
    of ``calibration`` (a :class:`Calibration` or a calibrated :class:`Model`) names a drift best,
    as ``kinecal check --plan`` chooses them: ``result["selected"]`` (row indices),
    ``result["wrong_names"]`` (the expected wrong names per pattern for a drift moving the tool
    ``drift_mm``) beside ``result["wrong_names_unplanned"]`` (the first ``n`` rows), and the pairs
    of patterns least apart (``result["weakest"]``)."""
    raw = calibration._raw if isinstance(calibration, Calibration) else calibration
    q = np.ascontiguousarray(configurations, dtype=np.float64)
    return json.loads(_kinecal.plan_check(raw, q, n=n, drift_mm=drift_mm, observe=observe))


def validate(model: Model, data: Data) -> Validation:
    """Per-pose errors of ``model`` on ``data`` (``kinecal validate``)."""
    return Validation(*_kinecal.validate(model, data))


def validate_instrument(model: Model, data: Data, seat_distances: Sequence[str] = ()) -> Dict[str, Any]:
    """``model`` judged on held-out instrument rows in the instrument's own terms (``kinecal
    validate`` of seat, distance or touch data): ``seats`` (each seat's spread, mm),
    ``distances`` (the known ``"A:B:MM"`` seat distances: a, b, known, modelled − known),
    ``pivots`` (each pivot's or reference sphere's length residuals), ``planes`` (each unknown
    plane's flatness) and ``cubes`` (each datum cube's fit), RMS and largest values in mm."""
    return json.loads(_kinecal.validate_instrument(model, data, list(seat_distances)))


def predict_accuracy(model: Model, configurations: np.ndarray) -> Dict[str, Any]:
    """The accuracy a calibrated ``model`` (a model file written by ``kinecal identify``, with its
    ``[covariance]``) predicts at ``configurations`` (n, inputs) in rad / mm (``kinecal validate
    --predict``): ``position_mm`` (n,) σ of the position (RMS 3-D error, mm),
    ``worst_axis_mm`` (n,), ``orientation_deg`` (n,), ``positions`` (n, 3) the predicted tool
    positions (mm), and ``noise_position_mm`` / ``noise_orientation_deg``, what one measurement
    adds."""
    q = np.ascontiguousarray(configurations, dtype=np.float64)
    r = json.loads(_kinecal.predict_accuracy(model, q))
    poses = r["poses"]
    return {
        "position_mm": np.array([p["position_mm"] for p in poses]),
        "worst_axis_mm": np.array([p["position_worst_axis_mm"] for p in poses]),
        "orientation_deg": np.array([p["orientation_deg"] for p in poses]),
        "positions": np.array([p["position"] for p in poses]).reshape(-1, 3),
        "noise_position_mm": r["noise_position_mm"],
        "noise_orientation_deg": r["noise_orientation_deg"],
    }


def identifiability(model: Model, data: Data, tolerance: float = 1e-8) -> Dict[str, Any]:
    """Rank, identifiable and redundant parameters, condition number (``kinecal identifiability``)."""
    return json.loads(_kinecal.identifiability(model, data, tolerance))


def assess(
    commanded: str, attained: str, distances: Optional[List[Tuple[int, int]]] = None, force: bool = False
) -> Dict[str, Any]:
    """ISO 9283 pose accuracy and repeatability (``poses``: AP_x/y/z/P, RP_l, …) and distance
    accuracy (``distances``) of an attained test file against the commanded test poses
    (``kinecal assess --json``; docs/assess.md). Attained poses beyond any plausible accuracy
    (a mean position error above 20 mm or orientation error above 5° at a test pose: files that
    do not belong together) raise ``KinecalError`` naming the worst pose, as ``kinecal assess``
    refuses them, unless ``force``."""
    return json.loads(_kinecal.assess(commanded, attained, list(distances or []), force))


def assess_circle(
    circle: str, radius: float, centre: Tuple[float, float, float] = (0.0, 0.0, 0.0), plane: str = "xy"
) -> Dict[str, Any]:
    """ISO 230-4 circular test (``kinecal assess --circle --json``): circular deviation G about the
    least-squares centre, radial deviation F_max / F_min about the nominal centre, centre offset
    (mm), from ballbar readings (angle_deg with radius_mm or deviation_mm) or points
    (x_mm,y_mm,z_mm about ``centre`` in ``plane``)."""
    return json.loads(_kinecal.assess_circle(circle, radius, list(centre), plane))


def plan_iso9283(
    model: Model,
    orientation_deg: Optional[Tuple[float, float, float]] = None,
    region: Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]] = None,
    *,
    grid: int = 10,
    samples: int = 500,
    seed: int = 1,
) -> Tuple[Dict[str, Any], np.ndarray]:
    """The ISO 9283 test poses P1–P5 in ``model``'s workspace (``kinecal plan --iso9283``): a summary
    (``side_mm``, ``cube_min_mm``, ``poses`` with positions and angles) and the commands (5, inputs)
    in rad / mm that reach them (docs/assess.md)."""
    o = None if orientation_deg is None else list(orientation_deg)
    r = None if region is None else (list(region[0]), list(region[1]))
    summary, commands = _kinecal.plan_iso9283(model, o, r, grid, samples, seed)
    return json.loads(summary), commands


def compensate(model: Model, targets: np.ndarray, seeds: Optional[np.ndarray] = None) -> np.ndarray:
    """Commands (n, inputs) in rad / mm that bring ``model`` to ``targets`` (n, 4, 4), mm
    (``kinecal compensate``)."""
    t = np.ascontiguousarray(targets, dtype=np.float64)
    s = None if seeds is None else np.ascontiguousarray(seeds, dtype=np.float64)
    return _kinecal.compensate(model, t, s)


def filter_program(
    calibrated: Model,
    nominal: Model,
    program: str,
    out: Optional[str] = None,
    *,
    format: Optional[str] = None,
    tool: Optional[np.ndarray] = None,
    max_deviation_mm: Optional[float] = None,
    force: bool = False,
) -> Dict[str, Any]:
    """A program's targets corrected for a controller that keeps its nominal kinematics
    (``kinecal filter``): ``T' = FK_nominal(IK_calibrated(T))`` on the program's configuration,
    every other byte kept. ``program`` is a file (CSV targets, RAPID ``.mod``, KRL ``.src`` with
    its ``.dat`` beside it, URScript, G-code); ``format`` when its extension does not say.
    ``tool`` (4×4, mm): the tool in the flange where the format has none (CSV, G-code).
    ``max_deviation_mm``: G-code and CSV moves split to stay within it of their lines.

    Returns a dict: ``text`` (the filtered program), ``companion`` (a KRL ``.dat``, or None),
    ``targets`` (line, name, before_mm, before_deg, after_mm, after_deg, shift_mm, shift_deg of
    each), ``paths`` (moves, added_points, largest_deviation_mm, arcs, … or None), ``notes``,
    ``uncorrected``. With ``out`` the text is also written there (and the ``.dat`` beside it)."""
    import os

    fmt = format
    if fmt is None:
        ext = os.path.splitext(program)[1].lower().lstrip(".")
        fmt = {"csv": "csv", "mod": "rapid", "modx": "rapid", "prg": "rapid", "src": "krl",
               "script": "urscript", "urscript": "urscript", "nc": "gcode", "ngc": "gcode",
               "gcode": "gcode"}.get(ext)
        if fmt is None:
            raise KinecalError(f"{program}: unknown program format (pass format=...)")
    with open(program, encoding="utf-8") as f:
        text = f.read()
    dat = os.path.splitext(program)[0] + ".dat"
    companion = None
    if fmt == "krl" and os.path.exists(dat):
        with open(dat, encoding="utf-8") as f:
            companion = f.read()
    t = None if tool is None else np.ascontiguousarray(tool, dtype=np.float64)
    new, new_dat, report = _kinecal.filter_program(
        calibrated, nominal, text, fmt, path=program, companion=companion, tool=t,
        max_deviation_mm=max_deviation_mm, force=force,
    )
    result = json.loads(report)
    result["text"] = new
    result["companion"] = new_dat
    if out is not None:
        if os.path.abspath(out) == os.path.abspath(program):
            raise KinecalError(f"{out}: the output would overwrite the program")
        with open(out, "w", encoding="utf-8", newline="") as f:
            f.write(new)
        if new_dat is not None:
            with open(os.path.splitext(out)[0] + ".dat", "w", encoding="utf-8", newline="") as f:
                f.write(new_dat)
    return result


def simulate(
    model: Model,
    poses: int,
    *,
    seed: int = 1,
    error_mm: float = 0.5,
    error_deg: float = 0.1,
    noise_mm: float = 0.0,
    noise_deg: float = 0.0,
    encoder_noise_deg: float = 0.0,
    encoder_noise_mm: float = 0.0,
    measure: str = "pose",
):
    """A virtual prototype (``kinecal simulate``): returns (true model, data measured at ``poses``
    random configurations, with the readings of the model's observed joints, ``Data.joints``).
    ``measure``: "pose", "position" or "reflectors"."""
    return _kinecal.simulate(
        model,
        poses,
        seed=seed,
        error_mm=error_mm,
        error_deg=error_deg,
        noise_mm=noise_mm,
        noise_deg=noise_deg,
        encoder_noise_deg=encoder_noise_deg,
        encoder_noise_mm=encoder_noise_mm,
        measure=measure,
    )


def plan(
    model: Model,
    candidates: np.ndarray,
    n: int = 30,
    *,
    criterion: str = "o2",
    method: str = "sffs",
    observe: str = "pose",
    noise_mm: float = 0.02,
    noise_deg: float = 0.02,
):
    """Choose ``n`` of the candidate configurations (N, inputs; rad / mm) to measure at
    (``kinecal plan``): greedy / SFFS / exchange on ``criterion`` (``d``, ``o1`` … ``o5``).
    Returns (chosen row indices, observability indices dict)."""
    c = np.ascontiguousarray(candidates, dtype=np.float64)
    chosen, indices = _kinecal.plan(
        model, c, n, criterion=criterion, method=method, observe=observe, noise_mm=noise_mm, noise_deg=noise_deg
    )
    return list(chosen), json.loads(indices)


class SampledPlan:
    """The result of :func:`plan_sampled`: the chosen candidate numbers, the summary
    (``kinecal plan --json``'s document plus the candidate generation report) and the plan CSV
    exactly as ``kinecal plan`` writes it."""

    def __init__(self, chosen: List[int], summary: str, csv: str) -> None:
        self.chosen = list(chosen)
        self.summary: Dict[str, Any] = json.loads(summary)
        self.csv = csv

    @property
    def indices(self) -> Dict[str, float]:
        """Observability indices of the chosen set (o1 … o5, o_t, log_det)."""
        return self.summary["indices"]

    @property
    def generation(self) -> Dict[str, int]:
        """Counts of the candidate generation (sampled, kept, unreachable, …)."""
        return self.summary["generation"]

    def save(self, path: str) -> None:
        """Write the plan CSV (the data-file format ``simulate --at`` and ``compensate`` read)."""
        with open(path, "w", encoding="utf-8", newline="") as f:
            f.write(self.csv)


def plan_sampled(model: Model, n: int = 30, **options: Any) -> SampledPlan:
    """Sample candidates of ``model`` and choose ``n`` of them: ``kinecal plan`` in one call (the
    same library function). Options as the command line's: ``x_mm``, ``y_mm``, ``z_mm``,
    ``alpha_deg``, ``beta_deg``, ``gamma_deg`` (a value or a pair; omitted: the model's own box,
    or, for a model without one given no range at all, its inputs within their limits),
    ``joint_range_deg`` (sample every input in ±range instead), ``grid`` (six counts or
    ``"paper"``), ``candidates``, ``seed``, ``max_condition``, ``criterion``, ``method``,
    ``observe``, ``noise_mm``, ``noise_deg``, ``pool``, ``shortlist``."""
    return SampledPlan(*_kinecal.plan_sampled(model, n, **options))


def plan_instrument(
    model: Model,
    points: Sequence[Tuple[float, float, float]],
    n: int = 40,
    **options: Any,
) -> Tuple[np.ndarray, List[int], Dict[str, Any]]:
    """Plan an instrument's rows on ``model``'s nominal geometry (``kinecal plan --seats`` /
    ``--pivots``, the same library call): ``points`` are the seats' centres (mm, base frame), or
    the pivots' with ``ballbar_mm``. Options: ``ballbar_mm``, ``tool_mm`` (the ball on the flange),
    ``candidates_per_point``, ``tilt_deg``, ``reference`` (rad / mm), ``min_per_point``,
    ``criterion``, ``method``, ``noise_mm``, ``seed``. Returns (the chosen configurations
    (n, inputs) in rad / mm, each row's point, summary dict)."""
    q, point_of, summary = _kinecal.plan_instrument(model, [list(p) for p in points], n, **options)
    return q, list(point_of), json.loads(summary)


def simulate_touches(model: Model, *, probe_radius_mm: float, **options: Any) -> Tuple[Model, Data]:
    """Touch-probe data on a virtual prototype (``kinecal simulate --spheres / --planes /
    --cube``): returns (true model, data). One kind per call: ``spheres`` (centres, mm) with
    ``sphere_diameter_mm``; ``planes`` ((point, normal) pairs); or ``cube`` (centre) with
    ``cube_edge_mm`` and ``cube_rotation_deg``. Other options: ``per_artifact`` (touches per
    sphere, plane or cube face), ``tool_mm`` (the probe ball on the flange), ``seed``,
    ``error_mm``, ``error_deg``, ``noise_mm`` (along each surface's normal)."""
    return _kinecal.simulate_touches(model, probe_radius_mm=probe_radius_mm, **options)


def plan_touches(model: Model, n: int = 40, *, probe_radius_mm: float, **options: Any) -> Tuple[Data, Dict[str, Any]]:
    """Plan where to touch on ``model``'s nominal geometry (``kinecal plan --spheres / --planes /
    --cube``, the same library call): the artifacts as in :func:`simulate_touches`, and
    ``tool_mm``, ``candidates_per_artifact``, ``min_per_artifact``, ``criterion``, ``method``,
    ``noise_mm``, ``seed``. Returns (the planned touches as data, summary dict)."""
    data, summary = _kinecal.plan_touches(model, n, probe_radius_mm=probe_radius_mm, **options)
    return data, json.loads(summary)
