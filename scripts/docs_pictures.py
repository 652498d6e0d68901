"""Draw the pictures of docs/napkin.md: the napkin's layout and one picture per state.

Run from the repository root:  .venv/bin/python scripts/docs_pictures.py
Everything is drawn from the package (the layout file, the simulator, the renderer) with
fixed seeds, so the pictures come out the same each time.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from dgli_vision.core.camera import look_at_table
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


def main() -> None:
    write_png(
        DOCS / "napkin_layout.png", sheet_image(napkin_drawing(default_layout()), px_per_mm=1.5)
    )
    for class_id in CLASS_IDS:
        write_png(DOCS / "states" / f"{class_id}.png", state_picture(class_id))


if __name__ == "__main__":
    main()
