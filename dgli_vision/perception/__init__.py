"""Perception: sticker detection by HSV thresholding, lifting to 3D, the table plane."""

from .detect import DetectorParams, StickerDetections, detect_stickers
from .lift import Markers3D, estimate_table_normal, lift_stickers

__all__ = [
    "DetectorParams",
    "Markers3D",
    "StickerDetections",
    "detect_stickers",
    "estimate_table_normal",
    "lift_stickers",
]
