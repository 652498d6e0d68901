"""Recorded frames reach worker processes through shared slots, not pickled pixels."""

import os
import pickle

import numpy as np

from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.parallel import SharedSlots
from dgli_vision.sources.recording import RecordedPair
from dgli_vision.sources.ros_images import ImagePayload


def _pair(seed: int, w: int = 64, h: int = 48) -> RecordedPair:
    rng = np.random.default_rng(seed)
    color = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    depth = rng.integers(0, 4000, (h, w), dtype=np.uint16)
    intr = Intrinsics(w, h, 50.0, 50.0, (w - 1) / 2, (h - 1) / 2)
    return RecordedPair(
        f"bag frame {seed} /color", f"bag frame {seed} /depth", "", None, None, 0.0,
        ImagePayload("rgb8", w, h, 3 * w, False, color.tobytes()),
        ImagePayload("16UC1", w, h, 2 * w, False, np.frombuffer(depth.tobytes(), np.uint8)),
        intr,
    )


def test_a_frame_sent_through_a_slot_loads_the_same_pixels_and_pickles_small():
    slots = SharedSlots(2)
    try:
        pair = _pair(1)
        sent, slot = pair.shared(slots)
        assert slot is not None
        wire = pickle.dumps(sent)
        assert len(wire) < 2000  # names and numbers, not 15 kB of pixels
        got, want = pickle.loads(wire).load(), pair.load()
        assert np.array_equal(got.color, want.color) and got.color.shape == (48, 64, 3)
        assert np.array_equal(got.depth_mm, want.depth_mm) and got.depth_mm.dtype == np.uint16
    finally:
        slots.close()
    assert not os.path.exists(slots.path)


def test_slots_are_reused_once_freed_and_a_full_ring_sends_the_frame_as_it_is():
    slots = SharedSlots(1)
    try:
        _, slot = _pair(1).shared(slots)
        assert slot is not None
        pair = _pair(2)
        same, none = pair.shared(slots)  # no free slot: the frame goes with its pixels
        assert none is None and same is pair
        slots.release(slot)
        again, slot2 = pair.shared(slots)
        assert slot2 == slot
        assert bytes(again.color_payload.data.view()) == bytes(pair.color_payload.data)
        bigger = _pair(3, w=128)  # larger than the slots made for the first frame
        assert bigger.shared(slots)[1] is None
    finally:
        slots.close()


def test_without_room_in_shared_memory_frames_go_with_their_pixels(monkeypatch):
    import errno

    def full(fd, offset, size):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "posix_fallocate", full, raising=False)
    slots = SharedSlots(2)
    pair = _pair(1)
    sent, slot = pair.shared(slots)
    assert slot is None and sent is pair  # sent the usual way, not a crash later
    slots.close()
