"""Type stubs of the kestrel package (see kestrel/__init__.py and each docstring)."""

from typing import Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str
OPTFLOW_USE_INITIAL_FLOW: int
OPTFLOW_LK_GET_MIN_EIGENVALS: int
TERM_CRITERIA_COUNT: int
TERM_CRITERIA_EPS: int

Frame = npt.NDArray[np.uint8]
Points = npt.NDArray[np.float32]
Illumination = Literal["gain_bias", "plain"]
Model = Literal["translation", "similarity", "affine", "homography"]

@overload
def calc_optical_flow_pyr_lk(
    prev: Frame,
    next: Frame,
    prev_pts: Points,
    next_pts: Optional[Points] = None,
    win_size: Union[Tuple[int, int], int, None] = (21, 21),
    max_level: int = 3,
    criteria: Optional[Tuple[int, int, float]] = (3, 30, 0.01),
    flags: int = 0,
    min_eig_threshold: float = 1e-4,
    illumination: Illumination = "gain_bias",
    return_reasons: Literal[False] = False,
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8], npt.NDArray[np.float32]]: ...
@overload
def calc_optical_flow_pyr_lk(
    prev: Frame,
    next: Frame,
    prev_pts: Points,
    next_pts: Optional[Points] = None,
    win_size: Union[Tuple[int, int], int, None] = (21, 21),
    max_level: int = 3,
    criteria: Optional[Tuple[int, int, float]] = (3, 30, 0.01),
    flags: int = 0,
    min_eig_threshold: float = 1e-4,
    illumination: Illumination = "gain_bias",
    *,
    return_reasons: Literal[True],
) -> Tuple[
    npt.NDArray[np.float32], npt.NDArray[np.uint8], npt.NDArray[np.float32], list[str]
]:
    """Pyramidal Lucas-Kanade as cv2.calcOpticalFlowPyrLK: (next_pts N x 1 x 2 float32,
    status N x 1 uint8, err N x 1 float32)."""

def good_features_to_track(
    image: Frame,
    max_corners: int,
    quality_level: float,
    min_distance: float,
    mask: Optional[npt.NDArray[np.uint8]] = None,
    block_size: int = 3,
    use_harris_detector: bool = False,
    k: float = 0.04,
) -> npt.NDArray[np.float32]:
    """Shi-Tomasi corners as cv2.goodFeaturesToTrack, N x 1 x 2 float32 (N may be 0)."""

@overload
def fast(
    image: Frame,
    threshold: int = 10,
    nonmax_suppression: bool = True,
    max_keypoints: Optional[int] = None,
    return_scores: Literal[False] = False,
) -> npt.NDArray[np.float32]: ...
@overload
def fast(
    image: Frame,
    threshold: int = 10,
    nonmax_suppression: bool = True,
    max_keypoints: Optional[int] = None,
    *,
    return_scores: Literal[True],
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]:
    """FAST-9 corners, N x 2 float32 (x, y), strongest first; with scores N uint32."""

def dense_flow(
    prev: Frame,
    next: Frame,
    cell: int = 8,
    *,
    window: int = 9,
    max_level: int = 3,
    min_eig_threshold: float = 7e-4,
    illumination: Illumination = "gain_bias",
    max_residual: float = 12.0,
    fill_passes: int = 2,
    smooth: bool = True,
    full_resolution: bool = False,
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.bool_]]:
    """Grid flow (rows, cols, 2) float32 (NaN: unknown) and measured-node mask (rows, cols);
    with full_resolution=True, (H, W, 2) and (H, W)."""

def flow_to_color(
    flow: npt.NDArray[np.float32],
    max_speed: Optional[float] = None,
    legend: bool = False,
    bgr: bool = False,
) -> npt.NDArray[np.uint8]:
    """Middlebury colour picture (H, W, 3) uint8 of an (H, W, 2) float32 flow."""

def estimate_motion(
    prev_pts: Points,
    next_pts: Points,
    model: Model = "homography",
    threshold: float = 1.0,
    max_iterations: int = 200,
    confidence: float = 0.995,
    min_inliers: int = 8,
    seed: Optional[int] = None,
) -> EgoMotion:
    """Robust (RANSAC) motion model between point pairs."""

def heartbeat_mavlink(system_id: int = 1, component_id: int = 100, sequence: int = 0) -> bytes:
    """A camera's HEARTBEAT as a MAVLink 2 frame."""

class FrameReport:
    """What the tracker did on one frame."""

    frame: int
    live: int
    tracked: int
    added: int
    refused: int
    revived: int
    detected: bool
    dropped: int
    dropped_fb: int
    dropped_residual: int
    dropped_appearance: int
    dropped_relocation: int
    dropped_out_of_frame: int
    dropped_lost: int
    dropped_ids: list[int]
    def as_dict(self) -> dict[str, object]: ...

class Tracker:
    """The library's KLT track manager (ids never reused, drops by gate, refill)."""

    def __init__(
        self,
        width: Optional[int] = None,
        height: Optional[int] = None,
        *,
        max_tracks: Optional[int] = None,
        preset: Optional[Literal["flow_sensor"]] = None,
        window: Optional[int] = None,
        max_level: Optional[int] = None,
        illumination: Optional[Illumination] = None,
        fb_threshold: Optional[float] = None,
        max_residual: Optional[float] = None,
        min_correlation: Optional[float] = None,
        least_correlation: Optional[float] = None,
        residual_ratio: Optional[float] = None,
        max_relocation: Optional[float] = None,
        relocate_every: Optional[int] = None,
        refill_cooldown: Optional[int] = None,
        refill_below: Optional[int] = None,
        leaving_within: Optional[int] = None,
        revive_within: Optional[int] = None,
    ) -> None: ...
    def process(self, frame: Frame) -> FrameReport: ...
    def start(self, frame: Frame) -> FrameReport: ...
    @property
    def ids(self) -> npt.NDArray[np.uint32]: ...
    @property
    def positions(self) -> npt.NDArray[np.float32]: ...
    @property
    def ages(self) -> npt.NDArray[np.uint32]: ...
    @property
    def born(self) -> npt.NDArray[np.uint32]: ...
    @property
    def residuals(self) -> npt.NDArray[np.float32]: ...
    @property
    def velocities(self) -> npt.NDArray[np.float32]: ...
    @property
    def size(self) -> Optional[Tuple[int, int]]: ...
    @property
    def frames(self) -> int: ...
    @property
    def totals(self) -> dict[str, int]: ...
    @property
    def config(self) -> Optional[dict[str, object]]: ...
    def __len__(self) -> int: ...

class MotionResult:
    """Moving-object boxes of one frame pair."""

    boxes: npt.NDArray[np.int32]
    boxes_next: npt.NDArray[np.int32]
    box_flow: npt.NDArray[np.float32]
    camera: npt.NDArray[np.float32]
    camera_inliers: int
    moving: int
    regions: int

class MotionDetector:
    """Moving-object detection along a sequence."""

    def __init__(
        self,
        width: Optional[int] = None,
        height: Optional[int] = None,
        *,
        cell: int = 8,
        persist_pairs: int = 2,
        outline: bool = True,
    ) -> None: ...
    def push(self, frame: Frame) -> Optional[MotionResult]: ...
    @property
    def size(self) -> Optional[Tuple[int, int]]: ...

class EgoMotion:
    """A fitted camera motion."""

    matrix: npt.NDArray[np.float64]
    inliers: Optional[npt.NDArray[np.bool_]]
    model: str
    status: str
    inlier_count: int
    rms_residual: float
    quality: int
    iterations: int
    @property
    def ok(self) -> bool: ...

class FlowReading:
    """An OPTICAL_FLOW_RAD reading and the OPTICAL_FLOW reading of the same integration."""

    @property
    def time_usec(self) -> int: ...
    @property
    def sensor_id(self) -> int: ...
    @property
    def integration_time_us(self) -> int: ...
    @property
    def integrated_x(self) -> float: ...
    @property
    def integrated_y(self) -> float: ...
    @property
    def integrated_gyro(self) -> Optional[Tuple[float, float, float]]: ...
    @property
    def temperature(self) -> int: ...
    @property
    def quality(self) -> int: ...
    @property
    def time_delta_distance_us(self) -> int: ...
    @property
    def distance(self) -> Optional[float]: ...
    @property
    def flow_rate(self) -> Tuple[float, float]: ...
    @property
    def flow_pixels(self) -> Tuple[int, int]: ...
    def optical_flow_rad_mavlink(
        self, system_id: int = 1, component_id: int = 100, sequence: int = 0
    ) -> bytes: ...
    def optical_flow_mavlink(
        self, system_id: int = 1, component_id: int = 100, sequence: int = 0
    ) -> bytes: ...

class FlowSensor:
    """The library's FlowSensor: the flow-sensor preset's reading, as firmware computes it."""

    def __init__(
        self,
        width: Optional[int] = None,
        height: Optional[int] = None,
        *,
        fov: float = 1.0,
        focal: Optional[float] = None,
        sensor_id: int = 0,
    ) -> None: ...
    def push(
        self,
        frame: Frame,
        interval_us: int,
        gyro: Optional[Tuple[float, float, float]] = None,
    ) -> Optional[EgoMotion]: ...
    def readout(self, time_usec: int) -> FlowReading: ...
    def set_distance(self, metres: float, sampled_at_us: int) -> None: ...
    @property
    def frames(self) -> int: ...
    @property
    def tracker_report(self) -> Optional[Tuple[int, int, int, int]]: ...

__all__: Sequence[str]
