"""Names of the capture conditions the renderer knows, in their own module so that the
command line can offer them without importing numpy (see :mod:`dgli_vision.sim.conditions`)."""

from __future__ import annotations

__all__ = ["COMBO_POOL", "CONDITION_HELP", "CONDITION_NAMES"]

#: Every condition ``dgli render --conditions`` knows, in the order of the robustness table.
CONDITION_NAMES: tuple[str, ...] = (
    "jpeg",
    "cast",
    "dim",
    "gloss",
    "sheen",
    "shadow",
    "clutter",
    "gripper",
    "grasp",
    "distortion",
    "distortion-known",
    "depth",
    "vga",
    "wood",
    "mirror",
    "backface",
    "depthscale",
    "photo",
    "far",
    "head",
    "combo",
)

#: The conditions ``combo`` draws three of: the first eleven, so that adding a condition
#: does not change what a seed's combinations are.
COMBO_POOL: tuple[str, ...] = (
    "jpeg",
    "cast",
    "dim",
    "gloss",
    "shadow",
    "clutter",
    "gripper",
    "distortion",
    "depth",
    "vga",
    "wood",
)

#: What each condition is, for help texts and reports.
CONDITION_HELP: dict[str, str] = {
    "jpeg": "colour saved as JPEG, quality 70-92",
    "cast": "no white balance: tungsten (R x1.25-1.45, B x0.55-0.72) or blue cast",
    "dim": "exposure 0.35-0.55 of normal, sensor noise sigma 6-10 levels",
    "gloss": "glossy stickers: a lamp's mirror highlight on one sticker",
    "sheen": "semi-gloss stickers under a large light: a corner's stickers washed to pastel "
    "(saturation 0.1-0.3), nothing blown out",
    "shadow": "a robot arm's soft shadow across the napkin (35-60% of the light)",
    "clutter": "3-6 saturated objects on the table (cups, boxes, caps, tape, a post-it)",
    "gripper": "a dark gripper and arm 60-200 mm above the napkin",
    "grasp": "a gripper holds the corner it folds: a fold in progress past 90 degrees or "
    "just laid flat (a corner rising below 90 degrees on a flat napkin), fingers on the "
    "corner's tip, the arm going up and away",
    "distortion": "uncorrected lens distortion (k1 0.06-0.12, k2 -0.06-0, p1, p2 within "
    "+-0.002), intrinsics unchanged",
    "distortion-known": "one such lens for the whole set, its coefficients written with the "
    "intrinsics",
    "depth": "flying pixels, parallax holes, 1-3 px registration offset, 2-4 mm noise, "
    "black mats without depth",
    "vga": "640 x 480, fx = fy = 500, camera 600-850 mm",
    "wood": "a light-wood table (saturation about 0.3, with grain)",
    "mirror": "the camera mirrors its image: colour and depth flipped left to right, "
    "intrinsics unchanged",
    "backface": "the napkin lies back face up (turned over about a horizontal axis; "
    "stickers on both faces)",
    "depthscale": "depth in the wrong units: x0.8 or x1.25, or x0.75-0.85 or x1.2-1.3",
    "photo": "the look of a photograph: a lamp at a finite distance (light falling off "
    "1.2-2x across the napkin) and a fill light of another colour temperature, a fabric "
    "sheen and laminated stickers, vignetting, auto exposure and white balance, a colour "
    "mosaic demosaiced",
    "far": "camera 0.7-1.0 m from the napkin, tilted up to 25 degrees",
    "head": "a robot's head camera: 1.0-1.2 m from the napkin, tilted 20-35 degrees",
    "combo": "three of jpeg ... wood at once",
}
