"""The sticker search judges its blobs, measures their centres and labels dark pixels in
batches: a batch must give each blob exactly what it would get alone."""

from __future__ import annotations

import cv2
import numpy as np

from dgli_vision.core.camera import DEFAULT_INTRINSICS
from dgli_vision.core.layout import default_layout
from dgli_vision.perception.blobs import Candidate, judge_blob, judge_blobs
from dgli_vision.perception.detect import _refine_all, candidate_blobs, search_image
from dgli_vision.perception.detections import DetectorParams
from dgli_vision.perception.labels import colour_labels, hue_lut
from dgli_vision.perception.napkin import find_napkin
from dgli_vision.perception.washed import pastel_params

LAYOUT = default_layout()
INTR = DEFAULT_INTRINSICS


def _scene():
    """Sixteen stickers on white cloth, a disc far too large, a strip, a crescent, a
    tilted-looking ellipse and a speck: blobs that pass and blobs that fail each check."""
    depth_mm = 500
    img = np.full((INTR.height, INTR.width, 3), 215, np.uint8)
    radius = LAYOUT.disc_diameter_mm / 2 * INTR.fx / depth_mm
    for sid in range(16):
        c = (int((100 + 70 * sid) * 16), int((200 + 17 * sid) * 16))
        disc, dot = LAYOUT.sticker_disc[sid], LAYOUT.sticker_dot[sid]
        cv2.circle(img, c, int(radius * 16), LAYOUT.colours_srgb[disc], -1, cv2.LINE_AA, 4)
        cv2.circle(img, c, int(0.4 * radius * 16), LAYOUT.colours_srgb[dot], -1, cv2.LINE_AA, 4)
    cv2.circle(img, (900, 560), 110, LAYOUT.colours_srgb["blue"], -1)
    cv2.rectangle(img, (200, 600), (290, 610), LAYOUT.colours_srgb["green"], -1)
    cv2.circle(img, (500, 600), int(radius), LAYOUT.colours_srgb["red"], -1)
    cv2.circle(img, (500 + int(radius), 600), int(radius), (215, 215, 215), -1)
    cv2.ellipse(img, (650, 620), (int(radius), int(radius / 2)), 30, 0, 360,
                LAYOUT.colours_srgb["yellow"], -1)
    cv2.circle(img, (1100, 650), 2, LAYOUT.colours_srgb["red"], -1)
    return img, np.full(img.shape[:2], depth_mm, np.uint16)


def _search(img, depth):
    params = DetectorParams()
    napkin = find_napkin(img, depth, INTR)
    lut, names = hue_lut(LAYOUT, params, None)
    image = search_image(img, depth, INTR, LAYOUT, params, napkin, lut, len(names))
    mask = cv2.threshold(image.labels, 0, 1, cv2.THRESH_BINARY)[1]
    contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    outer = [c for c, h in zip(contours, hierarchy[0]) if h[3] < 0]
    return image, outer, napkin, lut, params


def _same(a, b) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, Candidate):
        return (a.score, a.where, a.area, a.z_mm, a.disc, a.dot, a.origin, a.foreshortening) == (
            b.score, b.where, b.area, b.z_mm, b.disc, b.dot, b.origin, b.foreshortening
        ) and np.array_equal(a.region, b.region)
    return a == b


def test_blobs_judged_together_get_what_each_gets_alone():
    image, outer, *_ = _search(*_scene())
    together = judge_blobs(outer, image)
    alone = [judge_blob(c, image) for c in outer]
    assert len(together) == len(outer) > 20
    assert all(_same(a, b) for a, b in zip(together, alone))
    kinds = {type(j).__name__ for j in together}
    assert kinds == {"Candidate", "Rejection", "NoneType"}  # every outcome in the batch
    assert sum(isinstance(j, Candidate) for j in together) == 16


def test_centres_measured_together_equal_each_measured_alone():
    img, depth = _scene()
    image, _, napkin, lut, params = _search(img, depth)
    candidates, _ = candidate_blobs(image)
    assert image.halved and len(candidates) == 16
    together = _refine_all(img, napkin.lut, lut, params, candidates)
    for c in candidates:
        assert together[c] == _refine_all(img, napkin.lut, lut, params, [c])[c]
        # within a pixel of the halved search's centre, at full resolution
        assert np.hypot(*(np.array(together[c][0]) - (2 * np.array(c.where) + 0.5))) < 1.0


def test_colour_labels_by_one_table_are_those_of_every_threshold_pixel_by_pixel():
    rng = np.random.default_rng(3)
    norm = rng.integers(0, 256, (120, 90, 3), dtype=np.uint8)
    norm[:40] //= 4  # (dark pixels, where the chroma binds)
    lut, _ = hue_lut(LAYOUT, DetectorParams(), None)
    hsv = cv2.cvtColor(norm, cv2.COLOR_RGB2HSV).astype(int)
    h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    for params in (DetectorParams(), pastel_params(DetectorParams())):
        labels, _ = colour_labels(norm, lut, params)
        v_limit = np.ceil(params.min_chroma * 255 / params.min_saturation)
        coloured = (s >= params.min_saturation) & (v >= params.min_value)
        faint = (v < v_limit) & (s * v < params.min_chroma * 255)  # (dark, low chroma)
        expected = np.where(coloured & ~faint, lut[h], 0)
        assert (coloured & faint).sum() > 100 and (expected > 0).sum() > 1000
        np.testing.assert_array_equal(labels, expected)


def test_pastel_cells_on_the_napkin_alone_are_those_of_the_whole_frame():
    from dgli_vision.perception.washed import pale_cells

    img, depth = _scene()
    pastel = cv2.addWeighted(img, 0.35, np.full_like(img, 235), 0.65, 0)  # sheen-washed
    params = DetectorParams()
    napkin = find_napkin(pastel, depth, INTR)
    lut, _ = hue_lut(LAYOUT, params, None)
    everywhere, hsv = pale_cells(pastel, lut, params, napkin)
    assert everywhere.sum() > 50
    within = np.zeros_like(everywhere)
    within[20:40, 10:60] = True  # a part of the grid, away from its borders
    part, part_hsv = pale_cells(pastel, lut, params, napkin, within=within)
    assert (everywhere & within).any() and (everywhere & ~within).any()
    np.testing.assert_array_equal(part & within, everywhere & within)
    np.testing.assert_array_equal(part_hsv[within], hsv[within])
    assert not part_hsv[45:].any()  # (far from the part: not computed)


def test_a_search_within_a_region_judges_its_blobs_as_a_search_of_the_whole_frame():
    from dataclasses import replace

    img, depth = _scene()
    params = DetectorParams()
    napkin = find_napkin(img, depth, INTR)
    lut, names = hue_lut(LAYOUT, params, None)
    roi = np.zeros((90, 160), bool)
    roi[20:35, 30:90] = True  # cells of 8 pixels: some of the stickers
    part = search_image(img, depth, INTR, LAYOUT, params, napkin, lut, len(names), roi)
    whole = search_image(img, depth, INTR, LAYOUT, params, napkin, lut, len(names))
    assert not part.norm[-20:].any()  # (far from the region: not computed)
    inside = cv2.resize(
        roi.astype(np.uint8), whole.labels.shape[::-1], interpolation=cv2.INTER_NEAREST
    )
    masked = replace(whole, labels=whole.labels * inside)  # (labelled everywhere, then cut)
    np.testing.assert_array_equal(part.labels, masked.labels)
    found, rejected = candidate_blobs(part)
    again, rejected_again = candidate_blobs(masked)
    assert 0 < len(found) < 16
    assert all(_same(a, b) for a, b in zip(found, again)) and len(found) == len(again)
    assert rejected == rejected_again


def test_a_search_near_the_napkin_judges_its_blobs_as_a_search_of_the_whole_image():
    from dataclasses import replace

    from dgli_vision.perception.detect import detect_stickers

    img, depth = _scene()
    img[:150], img[520:], img[:, :40], img[:, 1240:] = 95, 95, 95, 95  # a grey table
    for x in (150, 450, 750, 1050):  # things on it, away from the napkin
        cv2.circle(img, (x, 640), 30, LAYOUT.colours_srgb["blue"], -1)
    cv2.circle(img, (560, 470), 12, LAYOUT.colours_srgb["green"], -1)  # a crescent on it
    cv2.circle(img, (572, 470), 12, (215, 215, 215), -1)
    params = DetectorParams()
    lut, names = hue_lut(LAYOUT, params, None)

    def near_and_whole():
        napkin = find_napkin(img, depth, INTR)
        near = search_image(img, depth, INTR, LAYOUT, params, napkin, lut, len(names))
        whole = search_image(
            img, depth, INTR, LAYOUT, replace(params, napkin_margin=None), napkin, lut,
            len(names),
        )
        return napkin, near, whole

    x0, y0, x1, y1 = near_and_whole()[1].within
    cv2.circle(img, (300, 2 * y1), 30, LAYOUT.colours_srgb["red"], -1)  # across its edge
    napkin, near, whole = near_and_whole()
    assert near.within == (x0, y0, x1, y1) and whole.within is None
    assert 0 < y1 - y0 < 0.8 * near.labels.shape[0]
    found, rejected = candidate_blobs(near)
    found_all, rejected_all = candidate_blobs(whole)
    assert len(found) == 16 and all(_same(a, b) for a, b in zip(found, found_all))
    far = [r for r in rejected_all if r not in rejected]  # (the table's things)
    assert len(far) == 5 and all(r.centroid[1] + np.sqrt(r.area_px) > y1 for r in far)
    assert rejected == [r for r in rejected_all if r not in far] and rejected
    a = detect_stickers(img, depth, INTR, LAYOUT, params, napkin=napkin)
    b = detect_stickers(img, depth, INTR, LAYOUT, replace(params, napkin_margin=None),
                        napkin=napkin)
    np.testing.assert_array_equal(a.centroids, b.centroids)
    np.testing.assert_array_equal(a.areas, b.areas)


def test_pastel_cells_from_the_cloth_regions_cells_are_those_averaged_again():
    from dgli_vision.perception.regions import cloth_regions
    from dgli_vision.perception.washed import PastelLooks, pale_cells

    img, depth = _scene()
    pastel = cv2.addWeighted(img, 0.35, np.full_like(img, 235), 0.65, 0)  # sheen-washed
    params = DetectorParams()
    napkin = find_napkin(pastel, depth, INTR)
    lut, _ = hue_lut(LAYOUT, params, None)
    regions = cloth_regions(pastel, napkin.white_rgb)
    assert regions.cells is not None and regions.cell_px == napkin.stride
    within = np.zeros(regions.labels.shape, bool)
    within[20:40, 10:60] = True
    looks = PastelLooks(pastel, napkin, regions)
    for part in (within, None):
        pale, hsv = looks.pale_cells(lut, params, part)
        again, again_hsv = pale_cells(pastel, lut, params, napkin, within=part)
        assert pale.sum() > 10
        np.testing.assert_array_equal(pale, again)
        np.testing.assert_array_equal(hsv, again_hsv)


def test_outer_contours_traced_level_by_level_are_those_of_one_search():
    from dgli_vision.perception.detect import outer_contours

    rng = np.random.default_rng(11)
    mask = (rng.random((240, 320)) < 0.45).astype(np.uint8)  # (components full of holes)
    mask[:, 100:104] = 0
    cv2.circle(mask, (200, 120), 60, 1, 8)  # a ring with components inside its hole
    mask[110:130, 190:210] = 1
    assert cv2.countNonZero(mask) > 8000
    together = outer_contours(mask, by_level=False)
    alone = outer_contours(mask, by_level=True)
    assert len(together) > 100
    assert len(alone) == len(together)
    assert all(np.array_equal(a, b) for a, b in zip(alone, together))
    assert len(outer_contours(mask)) == len(together)


def test_a_search_near_the_napkin_computes_its_images_only_as_far_as_its_blobs_reach():
    """The search image is computed in the box near the napkin and a pixel around it,
    then only as far as the windows of the blobs judged reach: nothing beyond the box
    while every blob lies well inside it; a blob by its edge is judged as in a search of
    the whole image, and the rows its window reaches are computed, no more."""
    from dataclasses import replace

    from dgli_vision.perception.blobs import window_pad

    img, depth = _scene()
    img[:150], img[520:], img[:, :40], img[:, 1240:] = 95, 95, 95, 95  # a grey table
    params = DetectorParams()
    lut, names = hue_lut(LAYOUT, params, None)
    napkin = find_napkin(img, depth, INTR)

    def near_and_whole():
        near = search_image(img, depth, INTR, LAYOUT, params, napkin, lut, len(names))
        whole = search_image(
            img, depth, INTR, LAYOUT, replace(params, napkin_margin=None), napkin, lut,
            len(names),
        )
        return near, whole

    near, _ = near_and_whole()
    _, y0, _, y1 = near.within
    assert near.halved and 0 < y0 and y1 + 30 < near.labels.shape[0]
    assert near.norm[y0 - 1 : y1 + 1].any()
    assert not near.norm[: y0 - 1].any() and not near.norm[y1 + 1 :].any()
    r = LAYOUT.disc_diameter_mm / 2 * INTR.fx / 500  # (full resolution)
    edge = (700, 2 * y1 - int(r) - 6)  # a sticker on the table, by the box's edge
    cv2.circle(img, edge, int(r), LAYOUT.colours_srgb["blue"], -1, cv2.LINE_AA)
    cv2.circle(img, edge, int(0.4 * r), LAYOUT.colours_srgb["red"], -1, cv2.LINE_AA)
    near, whole = near_and_whole()
    found, rejected = candidate_blobs(near)
    found_all, rejected_all = candidate_blobs(whole)
    assert len(found) == 16 and all(_same(a, b) for a, b in zip(found, found_all))
    by_edge = [j for j in rejected if j.centroid[1] > y1 - r]
    assert len(by_edge) == 1 and by_edge[0] in rejected_all  # (judged alike: off the cloth)
    assert "not on the napkin" in by_edge[0].reason
    bottom = (edge[1] + r) / 2 + window_pad(r / 2) + 2  # (its window's last row, and more)
    assert near.norm[y1 + 1 : int(bottom)].any() and not near.norm[int(bottom) + 1 :].any()


def test_a_search_again_leaves_the_stickers_found_to_them_and_finds_the_rest_alike():
    """The second search (``known``: the stickers found before) judges no blob covering
    a found sticker again, gives no one its id, and finds the others where a search of
    everything finds them."""
    from dgli_vision.perception.detect import detect_stickers

    img, depth = _scene()
    first = detect_stickers(img, depth, INTR, LAYOUT)
    assert first.found.sum() == 16
    known = first.centroids.copy()
    lost = np.array([1, 6, 11])
    known[lost] = np.nan
    report = ~np.isfinite(known).all(axis=1)
    again = detect_stickers(img, depth, INTR, LAYOUT, report=report, known=known)
    assert np.flatnonzero(again.found).tolist() == lost.tolist()
    assert np.allclose(again.centroids[lost], first.centroids[lost], atol=1e-9)
    # every sticker known: nothing is left to find, and no blob is taken for one
    none = detect_stickers(
        img, depth, INTR, LAYOUT, report=np.zeros(16, bool), known=first.centroids
    )
    assert not none.found.any()
    # (the blobs of the 13 stickers known are not traced for judging)
    params = DetectorParams()
    napkin = find_napkin(img, depth, INTR)
    lut, names = hue_lut(LAYOUT, params, None)
    args = (img, depth, INTR, LAYOUT, params, napkin, lut, len(names))
    every = search_image(*args).traced[1]
    rest = search_image(*args, known=known[~report]).traced[1]
    assert len(every) - len(rest) == 13
