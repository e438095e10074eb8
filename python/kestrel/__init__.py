"""Kestrel from Python: fixed-point pyramidal Lucas-Kanade optical flow for flight controllers.

The functions take and return numpy arrays with OpenCV's argument names, shapes and dtypes, so
an OpenCV script switches by changing the module name::

    import kestrel
    p0 = kestrel.good_features_to_track(old_grey, 100, 0.3, 7, block_size=7)
    p1, st, err = kestrel.calc_optical_flow_pyr_lk(old_grey, grey, p0, None,
                                                   win_size=(15, 15), max_level=2)

Frames are 2-D uint8 arrays. Rows may be a stride apart (a crop such as ``frame[10:100, 20:200]``
is viewed without a copy); pixels must be contiguous within a row, otherwise ``ValueError``
asks for ``np.ascontiguousarray``. Bad input raises ``TypeError`` (wrong type or dtype) or
``ValueError`` (shape, layout, sizes, settings out of range) with a message naming the
argument and the limit. The GIL is released while the library computes.

Beyond OpenCV's API: ``fast`` (FAST-9), ``Tracker`` (the KLT track manager with ids, drop
reasons and the flow-sensor preset), ``dense_flow`` and ``flow_to_color`` (grid flow and its
Middlebury colour picture), ``MotionDetector`` (moving-object boxes), ``estimate_motion``
(robust ego-motion) and ``FlowSensor`` (the OPTICAL_FLOW_RAD reading and its MAVLink bytes).
"""

from ._kestrel import (
    OPTFLOW_LK_GET_MIN_EIGENVALS,
    OPTFLOW_USE_INITIAL_FLOW,
    EgoMotion,
    FlowReading,
    FlowSensor,
    FrameReport,
    MotionDetector,
    MotionResult,
    Tracker,
    calc_optical_flow_pyr_lk,
    dense_flow,
    estimate_motion,
    fast,
    flow_to_color,
    good_features_to_track,
    heartbeat_mavlink,
)

#: OpenCV's TERM_CRITERIA_COUNT and TERM_CRITERIA_EPS, for ``criteria``.
TERM_CRITERIA_COUNT = 1
TERM_CRITERIA_EPS = 2

__version__ = "0.1.0"

__all__ = [
    "OPTFLOW_LK_GET_MIN_EIGENVALS",
    "OPTFLOW_USE_INITIAL_FLOW",
    "TERM_CRITERIA_COUNT",
    "TERM_CRITERIA_EPS",
    "EgoMotion",
    "FlowReading",
    "FlowSensor",
    "FrameReport",
    "MotionDetector",
    "MotionResult",
    "Tracker",
    "calc_optical_flow_pyr_lk",
    "dense_flow",
    "estimate_motion",
    "fast",
    "flow_to_color",
    "good_features_to_track",
    "heartbeat_mavlink",
]
