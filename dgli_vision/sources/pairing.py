"""Pair the frames of two image streams by nearest timestamp, as they stream in.

A recording holds colour and depth as separate messages; a frame is a colour image and
the depth image nearest to it in time, within a tolerance. Pairing is streamed: only the
few frames not yet settled are held, so memory does not grow with the episode. Nothing
is dropped silently: a frame with no partner is yielded alone.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Generic, Literal, TypeVar

__all__ = ["Paired", "pair_by_time"]

T = TypeVar("T")

#: a stream more than this far behind the other (seconds) is taken as having stopped
HORIZON_S = 2.0


@dataclass(frozen=True)
class Paired(Generic[T]):
    """A colour frame and its depth (either may be None: that frame had no partner)."""

    color: T | None
    depth: T | None
    color_time: float | None
    depth_time: float | None


def pair_by_time(
    events: Iterable[tuple[Literal["color", "depth"], float, T]], tolerance: float
) -> Iterator[Paired[T]]:
    """Pair each colour frame with the nearest depth frame within ``tolerance`` seconds.

    Parameters
    ----------
    events : iterable of (stream, time, item)
        ``stream`` is ``"color"`` or ``"depth"``; each stream in time order (the two may
        interleave in any order, as a recorder writes them).
    tolerance : float
        Largest time difference of a pair, in seconds.

    Yields
    ------
    Paired
        Colour frames in time order, each with its depth or alone; a depth frame that no
        colour frame took is yielded alone as soon as no later colour frame can take it.
    """
    colors: deque[tuple[float, T]] = deque()
    depths: deque[tuple[float, T]] = deque()
    last = {"color": float("-inf"), "depth": float("-inf")}

    def settle(final: bool) -> Iterator[Paired[T]]:
        while colors and (
            final
            or last["depth"] > colors[0][0] + tolerance
            or last["color"] - colors[0][0] > HORIZON_S
        ):
            t, item = colors.popleft()
            while depths and depths[0][0] < t - tolerance:  # too early for this or later
                td, d = depths.popleft()
                yield Paired(None, d, None, td)
            near = [k for k, (td, _) in enumerate(depths) if abs(td - t) <= tolerance]
            if near:
                k = min(near, key=lambda k: abs(depths[k][0] - t))
                td, d = depths[k]
                del depths[k]
                yield Paired(item, d, t, td)
            else:
                yield Paired(item, None, t, None)
        while depths and (
            final
            or (depths[0][0] + tolerance < last["color"] and not colors)
            or last["depth"] - depths[0][0] > HORIZON_S
        ):
            td, d = depths.popleft()
            yield Paired(None, d, None, td)

    for stream, t, item in events:
        (colors if stream == "color" else depths).append((t, item))
        last[stream] = max(last[stream], t)
        yield from settle(False)
    yield from settle(True)
