"""Perception: from an RGB-D frame to the stickers in 3D and what the missing ones say.

The stages run in the order the data flows, each receiving the frozen result of the one
before (:func:`dgli_vision.classifier.pipeline.observe` chains them):

1. the table plane (:mod:`.lift`) and the napkin (:mod:`.napkin`): its white, and masks
   of highlights, objects above the table and cloth held up (:class:`.napkin.NapkinView`);
   and the frame's white regions, where its cloth may be (:mod:`.regions`);
2. the stickers (:mod:`.detect`: steps on one search frame built once, the first
   search and the second for pastel stickers :mod:`.washed`; colour labels
   :mod:`.labels`, one blob judged :mod:`.blobs`; parameters and results, rejections
   with their kind and values, :mod:`.detections`);
3. 3D (:mod:`.lift`), with the napkin's scale (:mod:`.scale`);
4. evidence (:mod:`.evidence`): each missing sticker hidden by cloth or unknown, from
   the napkin view's masks (:meth:`.napkin.NapkinView.masks`);
5. flaps (:mod:`.flaps`): how far a flap held up has turned; and the footprint
   (:mod:`.footprint`, its cloth followed into an arm's shadow by :mod:`.shade`) and the
   face each corner shows (:mod:`.handedness`).

A stage's modules import only from earlier stages and from :mod:`dgli_vision.core`
(tests/test_perception_stages.py holds it).
"""

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
