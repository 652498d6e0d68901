"""Every parameter of the perception in one tree: :class:`PipelineParams`.

Each stage's parameters are one frozen dataclass here (the napkin, the white regions,
the sticker detector, the evidence of the missing stickers, the partly hidden ones,
flaps, an arm's shade, the footprint, the corners' tips), every field with its unit and
why it has its default; :class:`PipelineParams` holds one of each, and
:func:`~dgli_vision.classifier.pipeline.classify_frame`,
:func:`~dgli_vision.classifier.api.classify_pair` (``params=``) and the command line
(``--params FILE``, :func:`read_params`) take it. Sizes of the stickers are not
parameters: they are the layout's (:func:`disc_bands`).

This module imports no other perception module (stage 0: every stage reads it); the
stage modules re-export their own class (``perception.detect.DetectorParams`` is
:class:`DetectorParams`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields, is_dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..core.errors import InvalidInputError
from ..core.layout import NapkinLayout

__all__ = [
    "DetectorParams",
    "DiscBands",
    "EvidenceParams",
    "FlapParams",
    "FootprintParams",
    "NapkinParams",
    "PartialParams",
    "PipelineParams",
    "RegionParams",
    "ShadeParams",
    "TipParams",
    "disc_bands",
    "params_of",
    "read_params",
]


@dataclass(frozen=True)
class NapkinParams:
    """How the napkin is found. Every field has a unit and a reason.

    Attributes
    ----------
    stride : int
        Subsampling of the image for the statistics, pixels. Default 8: a 1280 x 720
        frame gives 14,400 samples (a VGA frame 4,800), plenty for medians, and a mask
        cell stays smaller than a sticker.
    bright_fraction : float
        Fraction of the (not blown-out) samples, brightest first, taken as the first
        guess of the napkin's white. Default 0.03: the napkin covers at least about 5% of
        any view SPEC allows (a half-folded napkin 850 mm away with a VGA camera: 9%).
    neutral_chroma : float
        Largest chroma (max - min channel over the napkin's level, after balancing) of a
        napkin pixel. Default 0.14: the napkin is unpatterned white or light grey; sensor
        noise of 10 levels gives chroma below 0.1.
    min_napkin_brightness : float
        Smallest linear brightness of a napkin pixel relative to the napkin's white.
        Default 0.45: above a matte table's reflectance against a white napkin under the
        same light; shadowed napkin is found again from its neighbours in the sticker
        stage, so this mask only refines the white estimate.
    target_level : int
        8-bit level the napkin's white is mapped to. Default 225: headroom for brighter
        folds and highlights.
    clipped_level : int
        8-bit level at which a channel counts as blown out. Default 250.
    highlight_level : float
        Linear brightness, relative to the napkin's own brightness around it (its white,
        or more where a lamp's fall-off or a sheen brightens it: ``level_window``), above
        which a near-white pixel is a highlight (nothing can be seen there). Default
        1.35: matte cloth facing the light is at most about 1.3 times its surround.
    level_window : int
        Width (samples) of the window the napkin's own brightness is averaged over.
        Default 9 (72 px at stride 8: two to five sticker diameters).
    highlight_chroma : float
        Largest chroma, relative to brightness, of a highlight pixel. Default 0.25: a
        mirror highlight is the lamp's colour (white once balanced), tinted at most
        slightly by the sticker under it.
    occluder_height_mm : float
        Height above the table plane above which a pixel that is not napkin-coloured is
        an object over the napkin. Default 15 mm: folded cloth lies within a few
        millimetres of the table, and a flap held up is napkin-coloured. Below
        ``raised_cloth_mm``, so that a gripper's fingers closing on the cloth (10-25 mm
        up) are an object, not cloth held up: the napkin-coloured rim of their depth
        edge would otherwise read as a flap standing at their height.
    occluder_darkness : float
        Linear brightness, relative to the napkin's white, below which a raised pixel is
        not napkin (a napkin in an arm's shadow keeps at least 0.3 of its light).
        Default 0.2.
    occluder_chroma : float
        Chroma, relative to brightness, above which a raised pixel is not napkin (a
        coloured object). Default 0.28: twice ``neutral_chroma``, so a tinted napkin flap
        held up is never taken for an object.
    raised_cloth_mm : float
        Height above the table plane above which a napkin-coloured sample is cloth held
        up (a flap being folded). Default 25 mm: wrinkles stay below about 10 mm and a
        folded layer adds a few.
    min_raised_samples : int
        Smallest connected patch of raised cloth samples taken as cloth held up.
        Default 6 (at stride 8, about 20 x 20 mm at 550 mm): flying pixels at depth
        edges come alone or in pairs.
    """

    stride: int = 8
    bright_fraction: float = 0.03
    neutral_chroma: float = 0.14
    min_napkin_brightness: float = 0.45
    target_level: int = 225
    clipped_level: int = 250
    highlight_level: float = 1.35
    level_window: int = 9
    highlight_chroma: float = 0.25
    occluder_height_mm: float = 15.0
    occluder_darkness: float = 0.2
    occluder_chroma: float = 0.28
    raised_cloth_mm: float = 25.0
    min_raised_samples: int = 6


@dataclass(frozen=True)
class RegionParams:
    """How the frame's white regions are found. Every field has a unit and a reason.

    Attributes
    ----------
    cell_px : int
        Side of the image cells averaged into one sample, pixels. Default 8: a cell is
        about 7 mm on the cloth at 520 mm, and averaging 64 pixels takes sensor noise of
        10 levels down to about 1.
    close_cells : int
        Side of the closing that fills the stickers' holes in the cloth mask, cells.
        Default 7: a 30 mm sticker spans 4-5 cells at the nearest camera.
    table_margin : float
        Least brightness above the median cell (the table: the napkin covers at most
        about a third of any view SPEC allows) of a cloth cell, relative to the napkin's
        white. Default 0.15: averaged cells of a table vary by a few hundredths.
    """

    cell_px: int = 8
    close_cells: int = 7
    table_margin: float = 0.15


@dataclass(frozen=True)
class DetectorParams:
    """How stickers are found. Every field has a unit and a default.

    Attributes
    ----------
    min_saturation : int
        Minimum HSV saturation (0-255) of a sticker pixel, in the image balanced to the
        napkin's white (:mod:`.napkin`). Default 115 (0.45): the printed colours keep
        over 0.6 even at their blurred rims, a light-wood table or a tinted surround
        stays near 0.3.
    min_value : int
        Minimum HSV value (0-255) in the balanced image, where the napkin's white is at
        ``NapkinParams.target_level`` (225): so this is relative to the napkin. Default
        30 (0.13 of the napkin): a blue sticker in a deep shadow of a dim image keeps
        about 0.25.
    min_chroma : int
        Minimum max - min channel (0-255) in the balanced image. Default 40 (0.18 of the
        napkin's level): dark noisy pixels can reach a high HSV saturation with a small
        chroma; a sticker in shadow keeps over 70.
    max_hue_distance : int
        Largest distance (OpenCV hue units, 2 degrees each) from a nominal hue. Default 22.
    min_area_ratio, max_area_ratio : float
        Accepted blob area relative to the disc area expected at the blob's depth.
        Defaults 0.55 and 2.0: a whole sticker seen at up to 15 degrees of tilt and on
        wrinkles keeps over 0.8; a sliver of a sticker mostly under a flap would give a
        centroid far from the sticker's centre, so it is better left out; two merged
        stickers are larger.
    blur_rim_px : float
        How far beyond the disc expected at a blob's centre, pixels, a blob smaller than
        ``min_area_ratio`` of that disc is grown over the blurred rim its colour
        threshold cut off (see :func:`.blobs` ``_grown_to_its_rim``). Default 3: a real
        camera's blur (a lens, an anti-aliasing filter, demosaicing) spreads an edge
        over a sigma of 1-1.6 pixels.
    small_radius_px : float
        Below this disc radius (pixels, in a search image at full resolution) a dot is
        read by the colour it adds to the disc's centre (by its labels where that
        cannot be read).
        Default 12: the 12 mm dot is then under 10 pixels across, and a real camera's
        blur leaves it few pixels of its own colour.
    small_saturation, small_chroma : int
        ``min_saturation`` and ``min_chroma`` of the pixels' labels in a search for
        small stickers (see ``small_radius_px``). Defaults 80 (0.31) and 30: a ring
        2-3 pixels wide between a dot and the cloth keeps 0.35-0.5 once blurred, a
        light-wood table stays near 0.3 and lies off the napkin.
    dot_min_share : float
        Least share of the dot's colour at the centre of such a sticker assumed when
        unmixing it (a plain disc's noise is not magnified more). Default 0.3: a 4-pixel
        dot under a blur of 1.6 pixels keeps about 0.5.
    dot_max_distance : float
        Largest difference, per channel, between the chroma direction of a small
        sticker's unmixed dot and the palette colour it is read as. Default 0.35.
    dot_margin : float
        How much nearer (per channel) the dot's colour must be than the next one for
        the dot to be read; otherwise it is left unread. Default 0.15: the palette's
        directions differ by 0.7 or more (red and yellow: in green).
    full_rim_px : float
        Rim (pixels) a saturation threshold cuts off a blurred disc, allowed for when a
        candidate of a halved search is measured again at full resolution. Default
        1.5: a real camera's blur (sigma 1-1.6 px) leaves a pale sticker 13 px in
        radius 0.53 of its disc above the threshold.
    rim_min_chroma : float
        Smallest chroma (linear, balanced to a napkin white of 0.75) of a pixel that
        tells a rim's colour. Default 0.08: the napkin's noise and a residual tint stay
        below 0.04; a sticker's rim mixed half and half with white keeps 0.15-0.4.
    rim_direction : float
        Largest difference, per channel, between a rim pixel's chroma direction (its
        linear channels less the smallest, over its chroma) and the blob's. Default
        0.25: white light mixed in keeps the direction; another sticker colour or a
        wood table differ by more than 0.4 in some channel.
    min_fill : float
        Minimum fraction of the expected disc, centred at the blob's centroid, that the
        blob covers. Default 0.6 (rejects crescents and slivers).
    min_solidity : float
        Minimum area / convex-hull area. Default 0.8.
    max_elongation : float
        Maximum ratio of the blob's principal axes. Default 2.5.
    min_purity : float
        Minimum fraction of the outer band with the disc colour, and of the inner part
        with the dot colour. Default 0.5.
    min_surround : float
        Minimum ratio of the surround's whiteness (median of the smallest linear channel
        on a ring 1.3-1.8 radii out) to the blob's brightness (median of its largest
        linear channel). Default 0.55: a sticker sits on white cloth (0.8 against at most
        0.83, so about 1 or more in any light), a cap or a box on a table does not (a
        grey table reflects at most 0.35 against 0.6 for a saturated object; a wood
        table's blue channel much less).
    min_dot_seen : float
        Minimum fraction of the dot area that is labelled with a colour (not washed out
        by a highlight) for the dot colour to be read. Default 0.35.
    highlight_min : int
        Smallest channel (0-255) of a washed-out pixel, in the image as taken or balanced
        to the napkin. Default 250: blown out, or brighter than white cloth can be.
    specular_margin : int
        How much brighter (8-bit levels, balanced image) than the cloth around it a
        pixel must be to count as a highlight when it is not blown out as taken; and
        half of it for a near-white halo pixel. Default 15 (about 1.15 times in linear
        light): a napkin's brighter side under a lamp's fall-off reaches 250 once
        balanced and is no highlight; a mirror highlight stands well above the cloth.
    highlight_halo_px : int
        Width of the pale halo around a blown-out highlight counted with it, pixels
        (pale: bright and below ``min_saturation``). Default 8: a mirror highlight fades
        into the sticker's colour over a few pixels, pale but not white.
    halo_min_saturation : int
        Smallest HSV saturation (0-255, balanced image) of a halo pixel. Default 30: the
        white napkin around a sticker stays below 20 once balanced, so the halo never
        spreads over the cloth.
    halo_min_value : int
        Smallest HSV value (0-255, balanced image) of a halo pixel; near-white pixels
        (every channel at least ``halo_min_value + 80``) count as halo whatever their
        saturation. Default 150: the halo is brighter than the sticker's own colour.
    highlight_reach : float
        How far from a blob's centre, in expected disc radii, washed-out pixels may be
        counted with it. Default 1.6: a highlight lies on the sticker, so within one
        radius of its true centre, and the centre of what is left of the colour lies
        at most about 0.6 radii off.
    napkin_blown_level : int
        8-bit level of the napkin's white at or above which highlights cannot be told
        from cloth, and none are recovered. Default 240.
    search_radius_px : float
        Stickers are searched in the image halved while a sticker at the median depth
        keeps at least this radius there, pixels; their centres are then measured at
        full resolution. Default 6: the dot (0.4 radii) keeps a core of a few clean
        pixels, and a 1280 x 720 frame from up to 750 mm is searched at 640 x 360.
    tilt_agreement : float
        Largest difference between the foreshortening read from a blob's shape (minor /
        major axis) and from the tilt of its own depth for it to be taken as a tilted
        disc. Default 0.25: the depth of a sticker's few hundred pixels gives the tilt
        to about 10 degrees; a half disc on flat cloth (shape 0.53, depth 1.0) fails.
    flat_foreshortening : float
        Above this cosine of the angle between the surface and the line of sight, a
        sticker is taken as seen face-on (the checks above apply unchanged). Default
        0.85 (32 degrees): SPEC's tilted cameras and wrinkles stay within it.
    min_foreshortening : float
        Below this cosine a sticker is seen too obliquely to be read (its dot shrinks
        to a line). Default 0.25 (75 degrees): the 12 mm dot keeps about 3 mm.
    washed_saturation : int
        ``min_saturation`` of the second search (:func:`.detect.find_washed_out`) for stickers a
        broad sheen washed to pastel. Default 25 (0.1): a semi-gloss sticker under a
        softbox keeps 0.1-0.3 and its hue, while the napkin once balanced stays below
        about 0.05.
    washed_surround : float
        ``min_surround`` of that search. Default 0.35: a semi-gloss sticker in the lobe
        of a large light reflects about twice what the matte cloth around it does.
    washed_margin_cells : int
        How far around the napkin's cells (the white regions holding the stickers found,
        cells of the napkin's sampling stride) the second search looks, in cells.
        Default 7 (56 px at stride 8): more than a sticker's width, so a washed sticker
        on the napkin's edge or a flap beside it stays inside; the table beyond, pastel
        too once balanced to the low level, is not searched.
    washed_level : int
        8-bit level the napkin's white is balanced to for that search. Default 150: a
        sticker under a sheen is brighter than the napkin, and at the usual 225 it would
        clip to white.
    washed_chroma : int
        ``min_chroma`` of that search. Default 20: a pastel sticker keeps the chroma of
        its own colour under added white light (in linear light exactly; 8-bit levels
        compress it), the napkin's noise stays below 10.
    napkin_margin : float or None
        How far beyond the napkin's white (the box around the napkin's cloth samples,
        ``NapkinView.cloth``) stickers are searched, in sticker diameters at the
        frame's median depth (at least 4 sampling strides). Only blobs lying
        wholly within the box so grown are judged and reported. Default 2: a sticker
        lies on the napkin, and where a shadow leaves the cloth beside it unseen as
        white, its centre still lies within the box of the white (at least a third of
        a radius inside it on 240 test frames); blobs farther out are things on the
        table. None: the whole image.
    """

    min_saturation: int = 115
    min_value: int = 30
    min_chroma: int = 40
    max_hue_distance: int = 22
    min_area_ratio: float = 0.55
    max_area_ratio: float = 2.0
    blur_rim_px: float = 3.0
    small_radius_px: float = 12.0
    small_saturation: int = 80
    small_chroma: int = 30
    dot_min_share: float = 0.3
    dot_max_distance: float = 0.35
    dot_margin: float = 0.15
    full_rim_px: float = 1.5
    rim_min_chroma: float = 0.08
    rim_direction: float = 0.25
    min_fill: float = 0.6
    min_solidity: float = 0.8
    max_elongation: float = 2.5
    min_purity: float = 0.5
    min_surround: float = 0.55
    min_dot_seen: float = 0.35
    highlight_min: int = 250
    specular_margin: int = 15
    highlight_halo_px: int = 8
    halo_min_saturation: int = 30
    halo_min_value: int = 150
    highlight_reach: float = 1.6
    napkin_blown_level: int = 240
    search_radius_px: float = 6.0
    tilt_agreement: float = 0.25
    flat_foreshortening: float = 0.85
    min_foreshortening: float = 0.25
    washed_saturation: int = 25
    washed_chroma: int = 20
    washed_level: int = 150
    washed_surround: float = 0.35
    washed_margin_cells: int = 7
    napkin_margin: float | None = 2.0


@dataclass(frozen=True)
class EvidenceParams:
    """How missing stickers are judged. Every field has a unit and a reason.

    Attributes
    ----------
    stretch_tolerance_mm : float
        How much farther apart two located stickers may be in 3D than on the flat napkin
        before one of them is a false detection. Default 15 mm: sticker centres are
        found to about 1 mm in x, y and a few mm in depth; wrinkles shorten distances.
    fit_tolerance_mm : float
        Residual of a sticker under a rigid fit for it to lie on the same flat part of
        the cloth. Default 10 mm: wrinkles are up to about 10 mm out of plane.
    napkin_margin_mm : float
        How near the napkin, in the image, an object above the table must come to be
        over it. Default 15 mm: the napkin's own outline is found to a sample or two, and
        an object set down beside the napkin keeps farther off.
    near_radii : float
        How close, in sticker radii, a missing sticker's predicted place must come to a
        highlight, an object or the image border to be unknown. Default 1.5: the
        prediction is good to a few millimetres, and half a sticker covered is enough to
        lose it.
    min_corner_support : int
        With an object over the napkin, a missing sticker is unknown unless at least this
        many stickers of its corner were seen. Default 3: a corner folded over moves its
        four stickers together, and three of them fix where the fourth lies; with fewer,
        its flap may lie under the object, if the object comes within
        ``flap_reach_mm`` of the sticker's flat place.
    object_band_samples : int
        Cloth held up that lies within this many mask samples of an object over the
        napkin throughout is not taken for a flap: at an object's edge the depth camera
        blends the object's depth with the cloth's (flying pixels), which reads as cloth
        standing up. Default 2 (16 px at the napkin masks' stride of 8).
    flap_beyond_samples : int
        Least number of mask samples of such cloth that lie beyond that band for it to be
        a flap. Default 10 (about 640 mm^2 at 520 mm): a gripper's lit faces and the
        blended depth along its edges make a few samples past the band; a flap it holds
        reaches 13 and more.
    flap_reach_mm : float
        How far from its flat place a corner folded over lays its stickers, at most, for
        :attr:`min_corner_support`. Default 150 mm.
    held_up_reach : float
        How near cloth held up (a flap being folded) must come to the place a missing
        sticker would have lying flat, as a fraction of the napkin's shorter side, for
        the sticker to be possibly on it, seen edge-on. Default 0.5: a flap turns about
        its fold line, and no sticker lies farther from a fold line than half the napkin.
    cover_mm : float
        How much higher than the napkin around it the surface over a missing sticker's
        flat place must stand for the sticker to be under a layer held above it (not on
        the raised flap itself). Default 12 mm: above wrinkles and a folded layer.
    steep_foreshortening : float
        A sticker seen more foreshortened than this (minor / major axis) lies on cloth
        held up steeply. Default 0.6 (53 degrees from flat): a flap turned past 120
        degrees lies over the napkin at a gentle angle and shows its stickers better.
    """

    stretch_tolerance_mm: float = 15.0
    fit_tolerance_mm: float = 10.0
    napkin_margin_mm: float = 15.0
    near_radii: float = 1.5
    min_corner_support: int = 3
    flap_reach_mm: float = 150.0
    object_band_samples: int = 2
    flap_beyond_samples: int = 10
    held_up_reach: float = 0.5
    cover_mm: float = 12.0
    steep_foreshortening: float = 0.6


@dataclass(frozen=True)
class PartialParams:
    """When a sticker at an object's edge is taken as seen.

    Attributes
    ----------
    min_colour : float
        Smallest share of the predicted disc (within ``disc_share`` of its radius) that
        shows the sticker's disc colour. Default 0.2: a crescent left by a gripper's edge
        keeps 0.2-0.7; the white napkin, the table and a dark gripper none.
    disc_share : float
        Share of the disc radius looked at around the predicted centre. Default 0.9.
    min_apart : float
        Smallest distance, in disc radii, from a sticker found of the same disc colour:
        the colour must be this sticker's, not a neighbour's. Default 2.5.
    min_dot : float
        Smallest share of the centre (the dot's size) that shows the sticker's dot
        colour, for a sticker confirmed at its place by its (disc, dot) pair
        (:func:`.partial.confirm_at_place`). Default 0.3: a blurred dot 3-4 px across
        at 1-2 m keeps 0.4-0.9 of its colour; another sticker's dot none.
    min_whole : float
        For a sticker whose dot has its disc's colour (no dot to centre it on): the
        smallest share of the ring that must show that colour, so that the centroid is
        the disc's centre and not a crescent's. Default 0.6.
    min_white : float
        Around a sticker confirmed at its place, the median of the smallest channel
        (balanced to the napkin's white) 1.3-1.8 radii out, as a share of that around
        the stickers found. Default 0.85: the napkin around a washed or cut sticker
        keeps 0.9-1.0; a grey table 0.65.
    min_sticker_px : float
        No sticker is confirmed at its place where stickers are smaller than this
        (pixels across at the depth of those seen): the classifier's capture limit
        (``classifier.capture_limits.MIN_STICKER_PX``, 10), below which identities are
        guesses.
    fit_tolerance_mm : float
        Inlier tolerance of the rigid fit of every sticker seen that says where to look
        for a missing one when the evidence stage predicts nothing. Default 10 mm, the
        evidence stage's.
    """

    min_colour: float = 0.2
    disc_share: float = 0.9
    min_apart: float = 2.5
    min_dot: float = 0.3
    min_whole: float = 0.6
    min_white: float = 0.85
    min_sticker_px: float = 10.0
    fit_tolerance_mm: float = 10.0


@dataclass(frozen=True)
class FlapParams:
    """How the lean of a flap is measured.

    Attributes
    ----------
    min_samples : int
        Depth samples of raised cloth needed for a slope. Default 8: a flap a few
        degrees from edge-on is a strip two or three samples wide and as long as the
        flap.
    min_height_span_mm : float
        The samples must span this much height. Default 20 mm: below that, the slope is
        set by depth noise (2-4 mm).
    reach : float
        Raised cloth counts for a missing sticker when it comes within this fraction of
        the napkin's shorter side of the sticker's flat place. Default 0.6: no point of
        a flap is farther from its fold line than half the napkin, plus the flap's own
        lean.
    outlier_mads : float
        Samples farther than this many median absolute deviations from the first fit
        (flying pixels at the flap's edge) are left out of the second. Default 3.
    max_pixels : int
        At most about this many raised pixels are used (evenly thinned): plenty for a
        slope, and a flap lying at 150 degrees covers a hundred thousand.
    """

    min_samples: int = 8
    min_height_span_mm: float = 20.0
    reach: float = 0.6
    outlier_mads: float = 3.0
    max_pixels: int = 5000


@dataclass(frozen=True)
class ShadeParams:
    """How the cloth is followed into a shadow. Every field has a unit and a reason.

    Attributes
    ----------
    dark_table : float
        Largest luminance of a table cell next to the cloth, relative to the median
        cell (the table), that suggests a shadow. Default 0.75: an arm's shadow keeps
        40-65% of the light; a table's own shading varies by a few per cent.
    dark_cells : int
        Fewest such cells that suggest a shadow. Default 8: an arm's shadow is 6 cm
        wide or more where it crosses the napkin's outline (over 15 cells of the ring
        when it crosses next to the cloth found); the check only saves time, the fill
        adds nothing where there is no shadow.
    sticker_chroma : float
        Chroma relative to luminance above which a cell is a sticker, not table.
        Default 1.2: a sticker's is 1.5-2.5, a wood table's under 1.
    ring_cells : int
        How far from the cloth (cells) such table is looked for. Default 3.
    margin_cells : int
        How far beyond the cloth's box (cells) the fill first looks; when the cloth in
        shade reaches further, the whole frame. Default 12 (about 8 cm on the table).
    step : float
        Largest ratio of the brightest to the darkest value of any colour channel in
        the 3 x 3 half-resolution pixels around a pixel the fill crosses. Default 1.4:
        a soft shadow's edge changes the light by a few per cent per pixel (at most
        about 20% over three); the napkin's outline is a step of a factor 1.7 or more
        between cloth and table in at least one channel (blurred over about two).
    fill_fraction : float
        Least fraction of a cell's pixels the fill must reach for the cell to be cloth.
        Default 0.5.
    """

    dark_table: float = 0.75
    dark_cells: int = 8
    sticker_chroma: float = 1.2
    ring_cells: int = 3
    margin_cells: int = 12
    step: float = 1.4
    fill_fraction: float = 0.5


@dataclass(frozen=True)
class FootprintParams(RegionParams):
    """How the footprint is measured: how the frame's white regions are found (the
    fields of :class:`.regions.RegionParams`: ``cell_px``, ``close_cells``,
    ``table_margin``), and how large a footprint is taken as measured. Every field has
    a unit and a reason.

    Attributes
    ----------
    max_fraction : float
        Largest footprint, relative to the napkin's area, taken as measured. Default
        1.06: a flat napkin measures within about 2% of its area; more means the table
        merged with the cloth.
    """

    max_fraction: float = 1.06


@dataclass(frozen=True)
class TipParams:
    """How the corners' places are looked at. Every field has a unit and a reason.

    Attributes
    ----------
    leg_mm, near_mm : float
        The band's samples lie where ``u + v`` (the distances along the corner's two
        edges, on the 400 mm napkin, scaled with the napkin's folds) is between
        ``near_mm`` and ``leg_mm``. Default 80-138: inside the smallest fold's reach
        (150 mm), and beyond the stickers (within 120 mm) an object hiding them hides.
    inset_mm : float
        Samples keep this far inside the napkin's edges. Default 15: a fit a few mm off
        and the cloth's edge pixels (mixed with the table) stay out.
    step_mm : float
        Spacing of the samples. Default 6: about one footprint cell at 520 mm.
    fit_tolerance_mm : float
        Stickers farther than this from the rigid fit are not of the napkin that stays.
        Default 12: wrinkles move a sticker by a few mm.
    min_face_cos : float
        Least cosine between the fitted napkin's front normal and the table's up. A fit
        face down is a flap folded over, not the napkin that stays. Default 0.9 (26
        degrees).
    min_table_share : float
        Least share of all the samples seen as table for the corner to be told.
        Default 0.25: a corner mostly under an object says nothing.
    """

    leg_mm: float = 138.0
    near_mm: float = 80.0
    inset_mm: float = 15.0
    step_mm: float = 6.0
    fit_tolerance_mm: float = 12.0
    min_face_cos: float = 0.9
    min_table_share: float = 0.25


@dataclass(frozen=True)
class DiscBands:
    """Where a sticker's colours are read, in radii of its disc from the blob's centre
    (elliptic for a foreshortened disc), worked out from the layout's disc and dot
    diameters (:func:`disc_bands`): never restated.

    Attributes
    ----------
    dot : float
        The inner part read as the dot: below :data:`DOT_SHARE` of the dot's radius
        (0.28 for the 12 mm dot of a 30 mm disc: the dot's rim blurs into the disc).
    centre : float
        The centre whose mean colour a small sticker's blurred dot is unmixed from:
        :data:`CENTRE_SHARE` of the dot's radius (0.2).
    band : (float, float)
        The outer band read as the disc: from a third of the way between the dot's rim
        and the disc's (0.6: clear of the dot's blur) to :data:`RIM_SHARE` of the disc
        (0.95: clear of the disc's own blurred rim).
    """

    dot: float
    centre: float
    band: tuple[float, float]


#: The share of the dot's radius read as the dot (:class:`DiscBands`).
DOT_SHARE = 0.7
#: The share of the dot's radius a blurred dot's colour is unmixed from.
CENTRE_SHARE = 0.5
#: The share of the disc's radius within which its colour is read (its rim blurs).
RIM_SHARE = 0.95


@lru_cache(maxsize=16)
def disc_bands(layout: NapkinLayout) -> DiscBands:
    """The :class:`DiscBands` of ``layout``'s stickers (their dot and disc diameters).

    Parameters
    ----------
    layout : NapkinLayout

    Returns
    -------
    DiscBands
    """
    q = layout.dot_diameter_mm / layout.disc_diameter_mm  # the dot's radius, in discs
    return DiscBands(DOT_SHARE * q, CENTRE_SHARE * q, (q + (1.0 - q) / 3.0, RIM_SHARE))


@dataclass(frozen=True)
class PipelineParams:
    """The parameters of every perception stage, one tree (each field a stage's frozen
    parameters, with its units and reasons there).

    Attributes
    ----------
    napkin : NapkinParams
        Stage 1: the napkin's white, highlights, objects and cloth held up.
    regions : RegionParams
        Stage 1: the frame's white regions.
    detector : DetectorParams
        Stage 2: the stickers (the first search, the pastel one, the partly hidden).
    evidence : EvidenceParams
        Stage 4: each missing sticker hidden by cloth or unknown.
    partial : PartialParams
        Stage 4: a sticker partly hidden, confirmed from its disc's colour.
    flaps : FlapParams
        Stage 5: how far a flap held up has turned.
    shade : ShadeParams
        Stage 5: the napkin's cloth followed into an arm's shadow.
    footprint : FootprintParams
        Stage 5: the table the napkin covers.
    tips : TipParams
        Stage 5: each corner's tip seen as bare table or cloth.
    """

    napkin: NapkinParams = field(default_factory=NapkinParams)
    regions: RegionParams = field(default_factory=RegionParams)
    detector: DetectorParams = field(default_factory=DetectorParams)
    evidence: EvidenceParams = field(default_factory=EvidenceParams)
    partial: PartialParams = field(default_factory=PartialParams)
    flaps: FlapParams = field(default_factory=FlapParams)
    shade: ShadeParams = field(default_factory=ShadeParams)
    footprint: FootprintParams = field(default_factory=FootprintParams)
    tips: TipParams = field(default_factory=TipParams)

    def with_overrides(self, overrides: dict[str, Any], source: str = "params") -> PipelineParams:
        """These parameters with ``overrides`` (``{"detector": {"min_saturation": 100}}``)
        in place.

        Raises
        ------
        InvalidInputError
            An unknown stage or field, or a value of the wrong type (one line naming
            ``source`` and the key).
        """
        if not isinstance(overrides, dict):
            raise InvalidInputError(f"{source}: expected a JSON object of stages, got "
                                    f"{type(overrides).__name__}")
        stages = {f.name: getattr(self, f.name) for f in fields(self)}
        out = {}
        for stage, values in overrides.items():
            if stage not in stages:
                raise InvalidInputError(
                    f"{source}: unknown stage {stage!r} (known: {', '.join(stages)})"
                )
            out[stage] = _overridden(stages[stage], values, f"{source}: {stage}")
        return replace(self, **out)

    def to_json(self) -> dict[str, dict[str, Any]]:
        """Every stage's fields and values (what :func:`read_params` reads back)."""
        return {
            f.name: {g.name: getattr(getattr(self, f.name), g.name)
                     for g in fields(getattr(self, f.name))}
            for f in fields(self)
        }


def _overridden(stage: Any, values: object, where: str) -> Any:
    """``stage`` (a stage's parameters) with ``values`` (a dict of its fields) set."""
    if not isinstance(values, dict):
        raise InvalidInputError(f"{where}: expected an object of fields, got {values!r}")
    known = {f.name: getattr(stage, f.name) for f in fields(stage)}
    out = {}
    for name, value in values.items():
        if name not in known:
            raise InvalidInputError(
                f"{where}: unknown field {name!r} (known: {', '.join(sorted(known))})"
            )
        default = known[name]
        if isinstance(default, bool) or is_dataclass(default):
            ok = isinstance(value, type(default))
        elif isinstance(default, int):
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif isinstance(default, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            value = float(value) if ok else value
        elif isinstance(default, tuple):
            ok = isinstance(value, list) and len(value) == len(default)
            value = tuple(value) if ok else value
        else:
            ok = isinstance(value, type(default))
        if not ok:
            raise InvalidInputError(
                f"{where}.{name}: expected {type(default).__name__} like {default!r}, "
                f"got {value!r}"
            )
        out[name] = value
    return replace(stage, **out)


def params_of(params: PipelineParams | DetectorParams | None) -> PipelineParams:
    """The parameters tree of ``params``: itself, the defaults with a stage-2
    :class:`DetectorParams` (what ``classify_frame`` took before the tree), or the
    defaults (None)."""
    if params is None:
        return PipelineParams()
    if isinstance(params, DetectorParams):
        return PipelineParams(detector=params)
    if isinstance(params, PipelineParams):
        return params
    raise InvalidInputError(
        f"params must be PipelineParams or DetectorParams; got {type(params).__name__}"
    )


def read_params(path: str | Path) -> PipelineParams:
    """The defaults with the overrides of a JSON file, ``{"stage": {"field": value}}``
    (what ``--params FILE`` reads).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    PipelineParams

    Raises
    ------
    InvalidInputError
        An unreadable file, not JSON, or an unknown stage or field (one line naming the
        file and the key).
    """
    try:
        data = json.loads(Path(path).read_text())
    except OSError as exc:
        raise InvalidInputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"{path}: not JSON ({exc})") from None
    return PipelineParams().with_overrides(data, str(path))
