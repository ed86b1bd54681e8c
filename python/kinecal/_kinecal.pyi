"""Type stubs of the compiled core (see kinecal/__init__.py for the documented API)."""
from typing import List, Optional, Tuple, Union

import numpy as np

__version__: str

class KinecalError(ValueError): ...

class Model:
    @staticmethod
    def load(name_or_path: str) -> "Model": ...
    @staticmethod
    def from_toml(text: str, name: str = "<string>") -> "Model": ...
    def to_toml(self) -> str: ...
    def to_controller(self, format: str) -> Tuple[str, str]: ...
    @staticmethod
    def from_controller(text: str, format: str, name: str = "<string>") -> "Model": ...
    @property
    def name(self) -> str: ...
    @property
    def inputs(self) -> List[str]: ...
    @property
    def observed(self) -> List[str]: ...
    @property
    def input_units(self) -> List[str]: ...
    @property
    def parameters(self) -> List[str]: ...
    def forward(self, q: np.ndarray) -> np.ndarray: ...
    def inverse(self, poses: np.ndarray, seeds: Optional[np.ndarray] = None) -> np.ndarray: ...

class Data:
    @staticmethod
    def read(path: str, model: Model) -> "Data": ...
    @staticmethod
    def from_arrays(
        model: Model,
        q: np.ndarray,
        positions: np.ndarray,
        rotations: Optional[np.ndarray] = None,
        ids: Optional[List[int]] = None,
        joints: Optional[np.ndarray] = None,
    ) -> "Data": ...
    def __len__(self) -> int: ...
    @property
    def ids(self) -> List[int]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def q(self) -> np.ndarray: ...
    @property
    def positions(self) -> np.ndarray: ...
    @property
    def joints(self) -> np.ndarray: ...

class Calibration:
    @property
    def model(self) -> Model: ...
    def report_json(self) -> str: ...
    def report_html(self) -> str: ...
    @property
    def blunders(self) -> List[int]: ...

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
    seat_distances: List[str] = ...,
    kind_noise: List[str] = ...,
    validation_seat_distances: List[str] = ...,
) -> Calibration: ...
class Update:
    @property
    def model(self) -> Model: ...
    def report_json(self) -> str: ...

def check(calibration: Union[Calibration, Model], data: Data, *, false_alarm: float = 0.01) -> str: ...
def update(prior: Union[Calibration, Model], data: Data, *, false_alarm: float = 0.01) -> Update: ...
def validate(model: Model, data: Data) -> Tuple[str, np.ndarray, Optional[np.ndarray]]: ...
def identifiability(model: Model, data: Data, tolerance: float = 1e-8) -> str: ...
def assess(commanded: str, attained: str, distances: List[Tuple[int, int]] = ..., force: bool = ...) -> str: ...
def assess_circle(circle: str, radius: float, centre: Tuple[float, float, float] = ..., plane: str = ...) -> str: ...
def plan_iso9283(
    model: Model,
    orientation_deg: Optional[Tuple[float, float, float]] = None,
    region: Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]] = None,
    grid: int = 10,
    samples: int = 500,
    seed: int = 1,
) -> Tuple[str, np.ndarray]: ...
def compensate(model: Model, targets: np.ndarray, seeds: Optional[np.ndarray] = None) -> np.ndarray: ...
def filter_program(
    calibrated: Model,
    nominal: Model,
    text: str,
    format: str,
    *,
    path: str = "<string>",
    companion: Optional[str] = None,
    tool: Optional[np.ndarray] = None,
    max_deviation_mm: Optional[float] = None,
    force: bool = False,
) -> Tuple[str, Optional[str], str]: ...
def predict_accuracy(model: Model, configurations: np.ndarray) -> str: ...
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
) -> Tuple[Model, Data]: ...
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
) -> Tuple[List[int], str]: ...
def plan_instrument(
    model: Model,
    points: List[List[float]],
    n: int = 40,
    *,
    ballbar_mm: Optional[float] = None,
    tool_mm: List[float] = ...,
    candidates_per_point: int = 100,
    tilt_deg: float = 30.0,
    reference: Optional[List[float]] = None,
    min_per_point: int = 0,
    criterion: str = "d",
    method: str = "sffs",
    noise_mm: float = 0.01,
    seed: int = 1,
) -> Tuple[np.ndarray, List[int], str]: ...
def plan_sampled(
    model: Model,
    n: int = 30,
    *,
    x_mm: Optional[Union[float, Tuple[float, float]]] = None,
    y_mm: Optional[Union[float, Tuple[float, float]]] = None,
    z_mm: Optional[Union[float, Tuple[float, float]]] = None,
    alpha_deg: Optional[Union[float, Tuple[float, float]]] = None,
    beta_deg: Optional[Union[float, Tuple[float, float]]] = None,
    gamma_deg: Optional[Union[float, Tuple[float, float]]] = None,
    joint_range_deg: Optional[float] = None,
    grid: Optional[Union[str, List[int]]] = None,
    candidates: int = 300000,
    seed: int = 1,
    max_condition: Optional[float] = None,
    criterion: str = "o2",
    method: str = "sffs",
    observe: str = "pose",
    noise_mm: float = 0.02,
    noise_deg: float = 0.02,
    pool: int = 10000,
    shortlist: int = 32,
) -> Tuple[List[int], str, str]: ...
def simulate_touches(
    model: Model,
    *,
    probe_radius_mm: float,
    spheres: List[List[float]] = ...,
    sphere_diameter_mm: Optional[float] = None,
    planes: List[Tuple[List[float], List[float]]] = ...,
    cube: Optional[List[float]] = None,
    cube_edge_mm: Optional[float] = None,
    cube_rotation_deg: List[float] = ...,
    per_artifact: int = 20,
    tool_mm: List[float] = ...,
    seed: int = 1,
    error_mm: float = 0.5,
    error_deg: float = 0.1,
    noise_mm: float = 0.0,
) -> Tuple[Model, Data]: ...
def plan_touches(
    model: Model,
    n: int = 40,
    *,
    probe_radius_mm: float,
    spheres: List[List[float]] = ...,
    sphere_diameter_mm: Optional[float] = None,
    planes: List[Tuple[List[float], List[float]]] = ...,
    cube: Optional[List[float]] = None,
    cube_edge_mm: Optional[float] = None,
    cube_rotation_deg: List[float] = ...,
    tool_mm: List[float] = ...,
    candidates_per_artifact: int = 100,
    min_per_artifact: int = 0,
    criterion: str = "d",
    method: str = "sffs",
    noise_mm: float = 0.005,
    seed: int = 1,
) -> Tuple[Data, str]: ...
def validate_instrument(model: Model, data: Data, seat_distances: List[str] = ...) -> str: ...
