"""The Motion stage of the pipeline: a design's motion traced once per window, its typed status,
and whether every designed end was reached (:mod:`fabkit.motion.traced`,
:mod:`fabkit.motion.ends`)."""

from .ends import MotionEnds, PortEnd, judge_ends
from .traced import TracedMotion, motion_for, trace_motion

__all__ = ["TracedMotion", "trace_motion", "motion_for", "MotionEnds", "PortEnd",
           "judge_ends"]
