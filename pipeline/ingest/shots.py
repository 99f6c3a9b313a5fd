"""Hard cuts between shots: ffmpeg's ``scdet`` scene-change filter, fed with frames that are
decoded anyway (the proposals' people cues decode every frame), so finding cuts costs no
second decode of the video.
"""

from __future__ import annotations

import av
import av.filter

WIDTH = 160          # scdet compares frames this wide: enough for a hard cut, cheap to filter
FIRST_SECONDS = 0.5  # scdet scores the first frames against black: cuts this early are not cuts


class CutFinder:
    """Push every decoded frame of a video in order; ``cuts()`` gives the hard cuts (seconds from
    the first frame pushed) whose scdet score is at least ``threshold`` (0-100)."""

    def __init__(self, threshold: float) -> None:
        self.threshold = float(threshold)
        self._graph = None
        self._shape = None
        self._origin = None
        self._cuts: list[float] = []

    def push(self, frame: av.VideoFrame) -> None:
        if self._origin is None:
            self._origin = (frame.pts or 0, frame.time_base)
        shape = (frame.width, frame.height, frame.format.name)
        if shape != self._shape:  # a stream whose size changes midway gets a new graph
            self._graph, self._shape = self._build(frame), shape
        self._graph.push(frame)
        while True:
            try:
                out = self._graph.pull()
            except (av.error.BlockingIOError, av.error.EOFError):
                return
            score = float(out.metadata.get("lavfi.scd.score", 0.0))
            if score >= self.threshold and out.pts is not None:
                pts, base = self._origin
                t = round(float((out.pts - pts) * (out.time_base or base)), 3)
                if t >= FIRST_SECONDS and t not in self._cuts:
                    self._cuts.append(t)

    def cuts(self) -> list[float]:
        return sorted(self._cuts)

    def _build(self, frame: av.VideoFrame):
        graph = av.filter.Graph()
        source = graph.add_buffer(width=frame.width, height=frame.height, format=frame.format,
                                  time_base=frame.time_base)
        # area averaging: the right filter for a large downscale, and half bicubic's cost here
        chain = [source, graph.add("scale", f"{WIDTH}:-2:flags=area"),
                 graph.add("scdet", f"threshold={self.threshold:g}:sc_pass=0"), graph.add("buffersink")]
        for a, b in zip(chain, chain[1:]):
            a.link_to(b)
        graph.configure()
        return graph

