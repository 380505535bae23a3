"""The frame ring by value: which frames it keeps, which 8 it picks for a window, and when it calls a window exact or
padded (the window rule of `touchanything.inference.engine.frame_ring`; SPAN = 15, interval 2)."""
from __future__ import annotations

import numpy as np

from touchanything.inference.engine.frame_ring import CachedFrame, FrameRing
from touchanything.inference.model.model_config import SPAN


def frame(i: int) -> CachedFrame:
    return CachedFrame(i, f"tokens {i}", np.zeros((42, 3), np.float32), np.ones(2, bool), ("ego",), 1000 * i)


def ring_of(indices) -> FrameRing:
    ring = FrameRing()
    for i in indices:
        ring.add(frame(i))
    return ring


def picked(window) -> list[int]:
    return [f.frame_index for f in window.frames]


def test_a_full_stream_gives_the_official_clip_and_keeps_exactly_the_last_span_frames():
    assert SPAN == 15
    ring = ring_of(range(31))
    assert ring.cached_indices() == list(range(16, 31)) and len(ring) == 15 and ring.newest == 30
    window = ring.window()
    assert picked(window) == [16, 18, 20, 22, 24, 26, 28, 30]
    assert window.exact and not window.padded
    assert [f.tokens for f in window.frames][-1] == "tokens 30"


def test_a_window_may_end_on_an_older_cached_frame():
    ring = ring_of(range(31))
    window = ring.window(end=29)
    assert picked(window) == [16, 17, 19, 21, 23, 25, 27, 29]  # 15 is evicted: its place takes 16, the nearest
    assert not window.exact and not window.padded
    assert picked(ring.window(end=30)) == [16, 18, 20, 22, 24, 26, 28, 30]
    assert ring.window(end=15) is None


def test_an_empty_ring_has_no_window():
    assert FrameRing().window() is None
    assert FrameRing().newest is None and len(FrameRing()) == 0


def test_after_a_start_the_positions_before_the_first_frame_take_the_first_frame():
    ring = ring_of(range(10, 21))
    window = ring.window()
    assert picked(window) == [10, 10, 10, 12, 14, 16, 18, 20]
    assert window.padded and not window.exact
    ring = ring_of(range(10, 25))
    window = ring.window()  # ideal 10 … 24: the first ideal frame is the first frame, not before it
    assert picked(window) == [10, 12, 14, 16, 18, 20, 22, 24]
    assert window.exact and not window.padded
    ring = ring_of(range(10, 24))
    assert ring.window().padded  # ideal 9 … 23


def test_a_dropped_frame_is_replaced_by_the_nearest_cached_one_ties_to_the_earlier():
    ring = ring_of([i for i in range(31) if i != 28])
    window = ring.window()
    assert picked(window) == [16, 18, 20, 22, 24, 26, 27, 30]
    assert not window.exact and not window.padded
    ring = ring_of([i for i in range(31) if i not in (27, 28, 29)])
    assert picked(ring.window()) == [16, 18, 20, 22, 24, 26, 26, 30]  # 26 and 30 are 2 from 28; 26 comes first
    ring = ring_of([i for i in range(31) if i not in (26, 27, 28)])
    assert picked(ring.window()) == [16, 18, 20, 22, 24, 25, 29, 30]


def test_a_frame_index_that_does_not_increase_is_a_seek_and_clears_the_ring():
    ring = ring_of(range(6))
    assert not ring.is_seek(6) and ring.is_seek(5) and ring.is_seek(0)
    assert not FrameRing().is_seek(0)
    ring.add(frame(5))
    assert ring.cached_indices() == [5] and ring.newest == 5
    window = ring.window()
    assert picked(window) == [5] * 8 and window.padded  # the first frame is 5 again
    ring.add(frame(2))
    assert ring.cached_indices() == [2]


def test_a_noted_index_without_a_frame_evicts_and_moves_newest():
    ring = ring_of(range(31))
    ring.note_index(40)
    assert ring.newest == 40 and ring.cached_indices() == list(range(26, 31))
    assert picked(ring.window()) == [26, 26, 26, 26, 26, 26, 28, 30]
    ring.note_index(45)
    assert ring.cached_indices() == [] and ring.window() is None
    ring.note_index(44)  # a seek: cleared, and 44 is the new first frame
    ring.add(frame(45))
    assert ring.cached_indices() == [45] and ring.window().padded


def test_clear_forgets_everything():
    ring = ring_of(range(20))
    ring.clear()
    assert len(ring) == 0 and ring.newest is None and ring.window() is None
    ring.add(frame(3))  # not a seek after clear: 3 is the first frame
    assert ring.cached_indices() == [3]
