"""Perception: from an RGB-D frame to the stickers in 3D and what the missing ones say.

:func:`.observe.observe` runs the stages once each, in the order the data flows, every
one adding its result to one :class:`.observe.Observation` and reading the frame
context the earlier ones worked out once (the table plane, the napkin found, the search
frame, the white regions); every stage's parameters are one tree
(:class:`.params.PipelineParams`, :mod:`.params`):

1. the table plane (:mod:`.lift`) and the napkin (:mod:`.napkin`): its white, and masks
   of highlights, objects above the table and cloth held up (:class:`.napkin.NapkinView`);
   and the frame's white regions, where its cloth may be (:mod:`.regions`);
2. the stickers (:mod:`.detect`: steps on one search frame built once, the first
   search and the second for pastel stickers :mod:`.washed`; colour labels
   :mod:`.labels`, the blobs judged :mod:`.blobs`; results, rejections with their kind
   and values, :mod:`.detections`);
3. 3D (:mod:`.lift`), with the napkin's scale (:mod:`.scale`);
4. evidence (:mod:`.evidence`): each missing sticker hidden by cloth or unknown, from
   the napkin view's masks (:meth:`.napkin.NapkinView.masks`), and a sticker partly
   hidden confirmed at its predicted place (:mod:`.partial`), the blobs seen edge-on
   (:mod:`.agreement`);
5. flaps (:mod:`.flaps`): how far a flap held up has turned; and the footprint
   (:mod:`.footprint`, its cloth followed into an arm's shadow by :mod:`.shade`), the
   face each corner shows (:mod:`.handedness`) and the corners' tips (:mod:`.tips`).

Helpers of any stage (stage 0): the rigid fit (:mod:`.rigid`) and the parameters
(:mod:`.params`). A stage's modules import only from earlier stages and from
:mod:`dgli_vision.core` (tests/test_perception_stages.py holds it); :mod:`.observe` and
the tools beside the frame's path (colour calibration :mod:`.calibrate`, the lens
:mod:`.lens`) come last.
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
