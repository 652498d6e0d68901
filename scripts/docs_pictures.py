"""Draw the pictures of docs/napkin.md: the napkin's layout, one picture per state and
the working envelope (a sticker's size in pixels against the camera's distance).

Run from the repository root:  .venv/bin/python scripts/docs_pictures.py
Everything is drawn from the package (the layout file, the simulator, the renderer) with
fixed seeds, so the pictures come out the same each time.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from dgli_vision.classifier.capture_limits import MIN_STICKER_PX, sticker_px
from dgli_vision.core.camera import DEFAULT_INTRINSICS, Intrinsics, look_at_table
from dgli_vision.core.classes import CLASS_IDS, CLASS_NAMES, VARIANTS
from dgli_vision.core.io import write_png
from dgli_vision.core.layout import default_layout
from dgli_vision.sim.cloth.states import sample_state
from dgli_vision.sim.render import Lighting, SensorModel, render
from dgli_vision.sim.sticker_sheet import napkin_drawing, sheet_image

DOCS = Path(__file__).resolve().parent.parent / "docs"
TILE_PX = 320


def state_picture(class_id: str) -> np.ndarray:
    """A clean render of the class's first variant, from straight above, cropped."""
    variant = VARIANTS[class_id][0]
    state = sample_state(
        class_id,
        variant,
        np.random.default_rng([7, int(class_id)]),
        wrinkles=False,
        placement=False,
    )
    pose = look_at_table(0.55, target=(0.0, 0.0, 0.0))  # the napkin is centred on the origin
    result = render(state, pose, lighting=Lighting(), sensor=SensorModel(enabled=False), rng=0)
    bgr = cv2.cvtColor(result.color, cv2.COLOR_RGB2BGR)
    h, w = bgr.shape[:2]
    side = min(h, w)
    crop = bgr[(h - side) // 2 : (h + side) // 2, (w - side) // 2 : (w + side) // 2]
    tile = cv2.resize(crop, (TILE_PX, TILE_PX), interpolation=cv2.INTER_AREA)
    label = f"{class_id} {CLASS_NAMES[class_id]}" + (f" ({variant})" if variant else "")
    cv2.putText(
        tile, label, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 3, cv2.LINE_AA
    )
    cv2.putText(tile, label, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    return tile


#: Common RGB-D colour cameras (name, width, height, fx): approximate focal lengths from
#: the cameras' published fields of view (the tool uses the intrinsics it is given).
CAMERAS = (
    ("nominal (SPEC's Azure Kinect, 1280 x 720)", DEFAULT_INTRINSICS.width,
     DEFAULT_INTRINSICS.height, DEFAULT_INTRINSICS.fx),
    ("RealSense D435 colour, 640 x 480", 640, 480, 615.0),
    ("RealSense D435 colour, 1280 x 720", 1280, 720, 920.0),
    ("Azure Kinect colour, 1920 x 1080", 1920, 1080, 910.0),
)
#: The distances of ``dgli render --engine cycles --envelope ...`` (metres).
RENDER_ENVELOPES = (("spec", 0.45, 0.80), ("far", 0.70, 1.00), ("head", 1.00, 1.20),
                    ("wide", 1.00, 2.00))


def envelope_picture() -> np.ndarray:
    """The working envelope: a sticker's diameter (px, face-on) against the napkin's
    distance for common cameras, the 10 px floor below which the answer is "cannot
    tell", and the render envelopes' distances (BGR)."""
    from dgli_vision.analysis.charts import _figure, _style, figure_bgr

    disc = default_layout().disc_diameter_mm
    dist = np.linspace(0.35, 3.2, 300)
    with _style():
        fig = _figure(7.5, 4.2)
        ax = fig.add_subplot(1, 1, 1)
        ax.axhspan(0, MIN_STICKER_PX, color="0.88", zorder=0)
        ax.axhline(MIN_STICKER_PX, color="0.3", lw=1)
        ax.text(0.4, MIN_STICKER_PX - 1.2, f'below {MIN_STICKER_PX:.0f} px: "cannot tell" '
                "with the size", ha="left", va="top", fontsize=9, color="0.25")
        styles = ("-", "--", "-", "-.")
        for (name, w, h, fx), ls in zip(CAMERAS, styles):
            intr = Intrinsics(w, h, fx, fx, (w - 1) / 2, (h - 1) / 2)
            size = [sticker_px(z * 1000, intr, disc) for z in dist]
            far = disc * fx / MIN_STICKER_PX / 1000
            ax.plot(dist, size, ls, lw=1.6, label=f"{name}, fx {fx:.0f}: 10 px at {far:.2f} m")
            ax.plot([far], [MIN_STICKER_PX], "o", color=ax.lines[-1].get_color(), ms=4)
        for k, (env, lo, hi) in enumerate(RENDER_ENVELOPES):
            y = 56 - 4 * k
            ax.plot([lo, hi], [y, y], color="0.35", lw=3, solid_capstyle="butt")
            ax.text(hi + 0.03, y, f"--envelope {env}", va="center", fontsize=8, color="0.25")
        ax.set_xlim(dist[0], dist[-1])
        ax.set_ylim(0, 60)
        ax.set_xlabel("napkin's distance from the camera (m)")
        ax.set_ylabel(f"sticker diameter ({disc:.0f} mm disc), px")
        ax.set_title("The working envelope: the sticker's size in the image")
        ax.legend(loc="center right", fontsize=8, bbox_to_anchor=(1.0, 0.47))
        ax.grid(alpha=0.3)
        return figure_bgr(fig)


def main() -> None:
    write_png(
        DOCS / "napkin_layout.png", sheet_image(napkin_drawing(default_layout()), px_per_mm=1.5)
    )
    for class_id in CLASS_IDS:
        write_png(DOCS / "states" / f"{class_id}.png", state_picture(class_id))
    write_png(DOCS / "envelope.png", envelope_picture())


if __name__ == "__main__":
    main()
