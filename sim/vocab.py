"""Names shared by every stage: environments, surfaces, obstacle kinds, materials, faults and labels.

These tuples are the contract between the simulator, the audio stage, the dataset and the detectors.
An index into one of them is what the trace stores; the names are what files and reports show.
"""

from __future__ import annotations

ENVIRONMENTS: tuple[str, ...] = ("indoor", "outdoor")
"""Where a scenario takes place; sets the arena, the allowed surfaces and the ambience."""

SURFACES: tuple[str, ...] = ("tile", "carpet", "concrete", "asphalt", "gravel", "grass")
"""Floor surfaces; roughness and friction in the physics, rolling noise in the audio."""

INDOOR_SURFACES: tuple[str, ...] = ("tile", "carpet", "concrete")
OUTDOOR_SURFACES: tuple[str, ...] = ("concrete", "asphalt", "gravel", "grass")

OBSTACLE_KINDS: tuple[str, ...] = ("wall", "door", "curb", "desk", "chair", "box", "luggage", "pedestrian")
"""Things the robot can collide with."""

MATERIALS: tuple[str, ...] = (
    "plaster",
    "wood_door",
    "concrete",
    "wood",
    "metal",
    "cardboard",
    "hard_plastic",
    "soft_body",
    "rubber",
)
"""Impact materials known to the audio stage (modal banks). `rubber` is the robot's bumper side."""

OBSTACLE_MATERIAL: dict[str, str] = {
    "wall": "plaster",
    "door": "wood_door",
    "curb": "concrete",
    "desk": "wood",
    "chair": "metal",
    "box": "cardboard",
    "luggage": "hard_plastic",
    "pedestrian": "soft_body",
}
"""The material each obstacle kind is made of."""

TRANSIENT_KINDS: tuple[str, ...] = ("seam", "threshold", "cable", "kerb_ramp", "debris")
"""Benign transients that nominal driving contains (not anomalies)."""

TRANSIENT_HEIGHT: dict[str, float] = {
    "seam": 0.004,
    "threshold": 0.015,
    "cable": 0.007,
    "kerb_ramp": 0.025,
    "debris": 0.008,
}
"""Height of each benign transient above the floor, m (the simulator builds the features with it; the trace
stores it with every event, `sim.trace.TransientEvents.height`)."""

FAULT_KINDS: tuple[str, ...] = ("flat_spot", "out_of_round", "bearing", "loose_wheel", "motor_degradation")
"""Wheel faults, each modelled in the physics."""

WHEELS_SKID4: tuple[str, ...] = ("front_left", "front_right", "back_left", "back_right")
WHEELS_DIFF2: tuple[str, ...] = ("left", "right")

LABELS: tuple[str, ...] = ("normal", "collision", "mechanical")
"""Label kinds: index 0, 1, 2 in per-sample label arrays."""

NORMAL, COLLISION, MECHANICAL = 0, 1, 2

SUB_KINDS: tuple[str, ...] = ("none", *OBSTACLE_KINDS, *FAULT_KINDS)
"""Sub-kind of a label: `none` for normal, an obstacle kind for a collision, a fault kind for a fault."""


def sub_kind_index(name: str) -> int:
    """Index of a sub-kind name in `SUB_KINDS`; raises ValueError naming the allowed values."""
    try:
        return SUB_KINDS.index(name)
    except ValueError:
        raise ValueError(f"unknown sub-kind {name!r}; allowed: {', '.join(SUB_KINDS)}") from None
