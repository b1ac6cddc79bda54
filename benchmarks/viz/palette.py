"""Colours shared by the 3D scene, the plots and the state lanes (RGBA, 0..255)."""

from __future__ import annotations

from sim.vocab import LABELS, OBSTACLE_KINDS, SURFACES

OBSTACLE_COLORS: dict[str, tuple[int, int, int, int]] = dict(
    zip(
        OBSTACLE_KINDS,
        [
            (190, 190, 180, 255),  # wall
            (150, 100, 60, 255),  # door
            (120, 120, 120, 255),  # curb
            (170, 120, 70, 255),  # desk
            (90, 110, 140, 255),  # chair
            (200, 160, 100, 255),  # box
            (60, 60, 70, 255),  # luggage
            (230, 180, 150, 255),  # pedestrian
        ],
        strict=True,
    )
)
"""Obstacle colour by kind."""

SURFACE_COLORS: dict[str, tuple[int, int, int, int]] = dict(
    zip(
        SURFACES,
        [
            (215, 215, 205, 255),  # tile
            (120, 90, 90, 255),  # carpet
            (160, 160, 155, 255),  # concrete
            (70, 70, 75, 255),  # asphalt
            (150, 135, 110, 255),  # gravel
            (90, 140, 70, 255),  # grass
        ],
        strict=True,
    )
)
"""Floor colour by surface."""

LABEL_COLORS: dict[str, tuple[int, int, int, int]] = dict(
    zip(LABELS, [(80, 170, 90, 255), (230, 120, 30, 255), (200, 50, 200, 255)], strict=True)
)
"""Ground-truth label colour: normal, collision, mechanical."""

BODY = (60, 110, 200, 255)
"""Robot body."""
WHEEL = (40, 40, 40, 255)
"""A healthy wheel."""
FAULTY_WHEEL = (230, 30, 30, 255)
"""A wheel while its fault is active."""
SPOKE = (230, 230, 230, 255)
"""The spoke that shows a wheel turning."""
FOLLOW_RING = (150, 175, 225, 255)
"""The faint ring around the robot that the 3D view follows."""
TRAJECTORY = (60, 110, 200, 160)
"""The driven path."""
CONTACT = (255, 90, 20, 255)
"""A collision marker."""
TRANSIENT = (150, 150, 150, 200)
"""A benign transient marker."""
QUIET = (70, 70, 70, 255)
"""The detector's lane while it stays below the threshold."""
NO_SCORE = (35, 35, 35, 255)
"""The detector's lane before its first window ends."""
IMU = (200, 140, 60, 255)
"""The IMU z velocity line."""

NAMED: tuple[tuple[str, tuple[int, int, int, int]], ...] = (
    ("red", (235, 90, 80, 255)),
    ("green", (90, 190, 90, 255)),
    ("blue", (90, 150, 245, 255)),
    ("yellow", (230, 200, 60, 255)),
    ("purple", (180, 110, 230, 255)),
    ("cyan", (70, 200, 210, 255)),
)
"""Line colours with the names the view titles use for them, in the order series get them."""


def series_colour(i: int) -> tuple[str, tuple[int, int, int, int]]:
    """(name, colour) of the i-th series of a multi-line plot."""
    return NAMED[i % len(NAMED)]


AXES: tuple[tuple[int, int, int, int], ...] = tuple(colour for _, colour in NAMED[:3])
"""x, y, z axis lines: red, green, blue."""
MICROPHONES: dict[str, tuple[int, int, int, int]] = {"left": NAMED[2][1], "right": NAMED[1][1]}
"""Left microphone blue, right green."""

SCORE = (40, 120, 220, 255)
"""The anomaly score line."""
THRESHOLD = (220, 40, 40, 255)
"""The threshold line."""
DETECTION = (255, 60, 60, 255)
"""Detection points and the detector's alarm state."""
CURSOR = (255, 255, 255, 255)
"""The time cursor over the spectrogram."""
LABEL = (45, 45, 50, 255)
"""Axis labels of the spectrograms (the viewer draws white text on the point's colour)."""
