"""What the sticker detector is told and what it returns.

:class:`DetectorParams` says how stickers are found (every field with its unit and
default), :class:`StickerDetections` what was found, and :class:`Rejection` each blob
that was not taken, with the check it failed (a :class:`RejectionKind`) and the values
measured: what a person debugging a real image needs, and what code downstream reads
(never the message, which is made from the data: :attr:`Rejection.reason`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

__all__ = ["DetectorParams", "Rejection", "RejectionKind", "StickerDetections"]


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


class RejectionKind(Enum):
    """The check a blob failed (its value: the words a message begins with).

    Each kind's measured values (:attr:`Rejection.values`), by key:

    - ``NO_DEPTH``: none (no depth reading to judge its size by);
    - ``OBLIQUE``: ``foreshortening`` (minor / major axis, below
      ``DetectorParams.min_foreshortening``);
    - ``TOO_SMALL``, ``TOO_LARGE``: ``z_mm`` (the blob's depth), ``ratio`` (its area over
      a disc's expected there), ``foreshortening`` (minor / major axis, as for
      ``OBLIQUE``; not for a blob judged again at full resolution) and, for a centre
      measured again at full resolution after a halved search, ``full_resolution``
      (True);
    - ``NOT_DISC_SHAPED``: ``solidity``, ``elongation``;
    - ``NOT_WHOLE_DISC``: ``fill`` (the share of the expected disc covered);
    - ``NOT_ON_NAPKIN``: ``surround`` (the whiteness around over the blob's brightness);
    - ``NO_DISC_COLOUR``, ``NO_DOT_COLOUR``: none;
    - ``MIXED_COLOURS``: ``purity``;
    - ``NO_SUCH_STICKER``: ``disc``, ``dot`` (colour names no sticker pairs);
    - ``SECOND_BLOB``: ``sticker`` (the id a better blob holds);
    - ``DOT_WASHED_OUT``: ``disc`` (its colour name), ``possible`` (stickers of that
      colour still free).
    """

    NO_DEPTH = "no depth"
    OBLIQUE = "seen too obliquely"
    TOO_SMALL = "too small"
    TOO_LARGE = "too large"
    NOT_DISC_SHAPED = "not disc-shaped"
    NOT_WHOLE_DISC = "not a whole disc"
    NOT_ON_NAPKIN = "not on the napkin"
    NO_DISC_COLOUR = "no disc colour inside"
    NO_DOT_COLOUR = "no dot colour inside"
    MIXED_COLOURS = "mixed colours"
    NO_SUCH_STICKER = "no such sticker"
    SECOND_BLOB = "second blob"
    DOT_WASHED_OUT = "dot washed out"


@dataclass(frozen=True)
class Rejection:
    """A blob that is not taken as a sticker: where, the check it failed and the values
    that check measured (keys by kind: :class:`RejectionKind`).

    Attributes
    ----------
    centroid : tuple of float
        (u, v), pixels.
    area_px : float
        The blob's area, pixels.
    kind : RejectionKind
    values : mapping of str to float, int or str
        What the check measured.
    """

    centroid: tuple[float, float]
    area_px: float
    kind: RejectionKind
    values: Mapping[str, float | int | str] = field(default_factory=dict)

    @property
    def reason(self) -> str:
        """The rejection in words, made from :attr:`kind` and :attr:`values`."""
        return _rejection_message(self.kind, self.values)

    @property
    def size_ratio(self) -> float | None:
        """The blob's area over a sticker's at its depth, for a blob rejected as too
        small or too large; None for any other kind."""
        if self.kind in (RejectionKind.TOO_SMALL, RejectionKind.TOO_LARGE):
            return float(self.values["ratio"])
        return None


def _rejection_message(kind: RejectionKind, values: Mapping[str, float | int | str]) -> str:
    """A rejection's words, from its kind and measured values (see
    :class:`RejectionKind` for the keys of each)."""
    v = values
    k = RejectionKind
    if kind is k.NO_DEPTH:
        return "no depth to judge its size"
    if kind is k.OBLIQUE:
        return f"seen too obliquely (foreshortened {v['foreshortening']:.2f})"
    if kind in (k.TOO_SMALL, k.TOO_LARGE):
        size = "of a disc" if kind is k.TOO_SMALL else "discs"
        where = " at full resolution" if v.get("full_resolution") else ""
        return (
            f"{kind.value} for a sticker at {v['z_mm']:.0f} mm ({v['ratio']:.2f} "
            f"{size}{where})"
        )
    if kind is k.NOT_DISC_SHAPED:
        return (
            f"not disc-shaped (solidity {v['solidity']:.2f}, elongation "
            f"{v['elongation']:.2f})"
        )
    if kind is k.NOT_WHOLE_DISC:
        return f"not a whole disc (covers {v['fill']:.2f} of one)"
    if kind is k.NOT_ON_NAPKIN:
        return f"not on the napkin (surround {v['surround']:.2f} as bright as the blob)"
    if kind is k.MIXED_COLOURS:
        return f"mixed colours (purity {v['purity']:.2f})"
    if kind is k.NO_SUCH_STICKER:
        return f"no sticker is {v['disc']} with a {v['dot']} dot"
    if kind is k.SECOND_BLOB:
        return f"second blob for sticker {v['sticker']} (lower score)"
    if kind is k.DOT_WASHED_OUT:
        return f"{v['disc']} disc with its dot washed out; {v['possible']} stickers possible"
    return kind.value  # (NO_DISC_COLOUR, NO_DOT_COLOUR: the words say it all)


@dataclass(frozen=True, eq=False)
class StickerDetections:
    """What the detector found.

    Attributes
    ----------
    centroids : ndarray, shape (16, 2)
        Sub-pixel centroid (u, v) of each sticker id; NaN where not found.
    areas : ndarray, shape (16,)
        Blob area in pixels (NaN where not found).
    scores : ndarray, shape (16,)
        Colour purity times shape agreement in [0, 1] (0 where not found).
    depth_mm : ndarray, shape (16,)
        Median valid depth inside the blob, mm (NaN where none).
    rejected : tuple of Rejection
        Blobs that looked like candidates but were rejected, with the check each
        failed and its values.
    foreshortening : ndarray, shape (16,), optional
        Minor / major axis of each sticker's image (1 face-on; lower on a tilted
        flap); NaN where not found.
    pale_px : ndarray, shape (k, 2), optional
        Pixels (x, y) of pastel sticker colour left away from every sticker found: a
        broad sheen's washed-out stickers that no search could read (see
        :func:`.detect.find_washed_out`).
    pale_colours : tuple of str
        The sticker colours (names) of two or more of those samples.
    """

    centroids: NDArray[np.float64]
    areas: NDArray[np.float64]
    scores: NDArray[np.float64]
    depth_mm: NDArray[np.float64]
    rejected: tuple[Rejection, ...] = field(default_factory=tuple)
    foreshortening: NDArray[np.float64] | None = None
    pale_px: NDArray[np.float64] | None = None
    pale_colours: tuple[str, ...] = ()

    @property
    def found(self) -> NDArray[np.bool_]:
        """Which sticker ids were detected, shape (16,)."""
        return ~np.isnan(self.centroids[:, 0])
