"""What to render: named camera views and a validated render request (:class:`RenderSpec`).

Participants compare postures across pictures (the paper's image observations ``o_i, o_j``),
so every view keeps the same scale: a tracking camera at a fixed distance from the root
body's subtree centre of mass, which keeps the whole body centred whatever the state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from engine.errors import InputError

if TYPE_CHECKING:  # mujoco loads where an env is built, not in web processes
    import mujoco

ImageFormat = Literal["jpg", "png"]
FORMATS: tuple[str, ...] = ("jpg", "png")
_FORMAT_ALIASES = {"jpg": "jpg", "jpeg": "jpg", "png": "png"}
MIN_SIZE = 16
MAX_SIZE = 1920
DEFAULT_SIZE = 480
THUMBNAIL_SIZE = 160
JPEG_QUALITY = 85


@dataclass(frozen=True)
class View:
    """A tracking camera on body 1 (the torso of Gymnasium's MuJoCo robots).

    Attributes:
        name: the name users pass (``side``, ``three-quarter``, ``front``).
        azimuth: degrees; 90 looks along +y, so a robot walking along +x moves rightwards.
        elevation: degrees, negative looks down.
        distance: metres from the tracked centre of mass.
    """

    name: str
    azimuth: float
    elevation: float = -10.0
    distance: float = 3.0

    def camera(self) -> mujoco.MjvCamera:
        """A MuJoCo camera for this view, tracking body 1."""
        import mujoco

        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = 1
        cam.azimuth, cam.elevation, cam.distance = self.azimuth, self.elevation, self.distance
        return cam


#: Robots face +x at reset; azimuth 180 puts the camera ahead of them, looking back.
VIEWS: dict[str, View] = {
    v.name: v
    for v in (
        View("side", azimuth=90.0),
        View("three-quarter", azimuth=135.0),
        View("front", azimuth=180.0),
    )
}
DEFAULT_VIEW = "side"


@dataclass(frozen=True)
class RenderSpec:
    """How to render a state: view, square size in pixels, image format, quality.

    Attributes:
        view: a key of :data:`VIEWS`.
        size: width = height in pixels, :data:`MIN_SIZE` .. :data:`MAX_SIZE`.
        fmt: ``jpg`` (default; ``jpeg`` accepted) or ``png``.
        quality: ``False`` for fast settings (no multisampling, shadows or reflections, about
            8x faster on CPU); ``True`` for figures.

    Raises:
        InputError: any field is out of range (raised on construction).
    """

    view: str = DEFAULT_VIEW
    size: int = DEFAULT_SIZE
    fmt: ImageFormat = "jpg"
    quality: bool = False

    def __post_init__(self) -> None:
        if self.view not in VIEWS:
            raise InputError(f"unknown view {self.view!r}: expected one of {', '.join(VIEWS)}")
        if (
            isinstance(self.size, bool)
            or not isinstance(self.size, int)
            or not MIN_SIZE <= self.size <= MAX_SIZE
        ):
            raise InputError(
                f"image size must be an integer in {MIN_SIZE}..{MAX_SIZE} pixels, got {self.size!r}"
            )
        fmt = _FORMAT_ALIASES.get(str(self.fmt).lower())
        if fmt is None:
            raise InputError(f"unknown image format {self.fmt!r}: expected jpg or png")
        object.__setattr__(self, "fmt", fmt)  # normalise 'jpeg'/'JPG' so cache keys agree

    @classmethod
    def thumbnail(cls, view: str = DEFAULT_VIEW, fmt: ImageFormat = "jpg") -> RenderSpec:
        """A small preview (:data:`THUMBNAIL_SIZE` pixels), e.g. for bracket pages."""
        return cls(view=view, size=THUMBNAIL_SIZE, fmt=fmt)

    @property
    def supersample(self) -> int:
        """Render at this multiple of ``size`` and shrink: small fast renders alias badly."""
        return 2 if self.size <= 2 * THUMBNAIL_SIZE and not self.quality else 1

    @property
    def media_type(self) -> str:
        """The HTTP content type of the encoded image."""
        return "image/jpeg" if self.fmt == "jpg" else "image/png"
