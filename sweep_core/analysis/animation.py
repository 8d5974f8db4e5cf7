"""Video files from RGB frames: MP4 (H.264, yuv420p) through imageio-ffmpeg's ffmpeg, GIF
through Pillow (:func:`open_writer`), and the output's path and format (:func:`output_path`:
a name ending in .mp4 or .gif), and the memory a render takes, refused before it starts above
a bound (:func:`check_memory`). Both write to the temporary file of
:func:`sweep_core.io.outputs.replacing`, renamed over the output once every frame is in."""
from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from sweep_core.errors import SweepError
from sweep_core.io.outputs import replacing

#: the highest frame rate of a GIF (1/s): it holds each frame a whole number of 10 ms, and a
#: frame shorter than that is shown for 100 ms by browsers
GIF_MAX_FPS = 100.0
#: x264's encoding threads and the frames it looks ahead (:class:`Mp4Writer`)
X264_THREADS, X264_LOOKAHEAD = 2, 10
#: the most memory (bytes) a GIF's render may take (:func:`gif_memory`)
GIF_BYTES = 1_000_000_000
#: memory of a GIF's render, bytes per pixel of the frame: once (the figure's RGBA canvas,
#: its RGB copy, the quantizing and Pillow's writer) and per frame (the quantized frame held
#: until the file is written, and the writer's copy of it). Measured increase of the peak
#: resident memory over the render: 1000 x 1000 px, 2 / 4 / 10 / 30 frames: 20 / 31 / 42 /
#: 71 MB; 1200 x 1200 px, 4 / 16 frames: 40-51 / 81 MB; 2000 x 2000 px, 2 / 10 frames: 91 /
#: 172 MB; 8192 x 8192 px, 11 frames: 3 GB (test/test_estimates.py checks it)
GIF_ONCE_PER_PX, GIF_FRAME_PER_PX = 22, 2
#: the most memory (bytes) an MP4's render may take, the render and its ffmpeg together
#: (:func:`mp4_memory`)
MP4_BYTES = 2_000_000_000
#: memory of an MP4's render: ffmpeg's own (MP4_BASE bytes) and bytes per pixel of the frame
#: once (the figure's canvas and RGB copy, about 10; x264's buffers, about 12) and per frame
#: sent, up to MP4_FRAMES frames (x264's frames in flight, with 2 threads and 10 frames of
#: lookahead, :data:`X264_THREADS`). Measured peak resident
#: memory of ffmpeg (through a wrapper process) plus the increase of the render's: 2000 x
#: 2000 px, 1 / 2 / 5 / 10 / 15 / 20 / 30 / 80 frames: ffmpeg 88 / 125 / 208 / 309 / 385 /
#: 416 / 447 / 474 MB, the render 41 MB; 1000 x 1000 px, 1 / 80 frames: 56 / 163 MB and
#: 8-13 MB (test/test_estimates.py checks it)
MP4_BASE, MP4_ONCE_PER_PX, MP4_FRAME_PER_PX, MP4_FRAMES = 50_000_000, 22, 5.5, 19


def has_encoder() -> bool:
    """imageio-ffmpeg is installed and finds an ffmpeg binary."""
    try:
        import imageio_ffmpeg
        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError, OSError):
        return False
    return True


def gif_memory(frames: int, size: tuple[int, int]) -> int:
    """The memory (bytes) a GIF of ``frames`` frames of ``size`` (width, height) px takes
    while it is rendered and written (:data:`GIF_ONCE_PER_PX`, :data:`GIF_FRAME_PER_PX`)."""
    return size[0] * size[1] * (GIF_ONCE_PER_PX + frames * GIF_FRAME_PER_PX)


def mp4_memory(frames: int, size: tuple[int, int]) -> int:
    """The memory (bytes) an MP4 of ``frames`` frames of ``size`` (width, height) px takes
    while it is rendered and encoded, ffmpeg's included (:data:`MP4_BASE` and the rest)."""
    per_px = MP4_ONCE_PER_PX + min(frames, MP4_FRAMES) * MP4_FRAME_PER_PX
    return int(MP4_BASE + size[0] * size[1] * per_px)


def check_memory(path: str, fmt: str, frames: int, size: tuple[int, int]) -> None:
    """Refuses, before any frame is drawn, a render of ``frames`` frames of ``size`` (width,
    height) px whose memory estimate passes :data:`GIF_BYTES` (``fmt`` "gif", assembled in
    memory) or :data:`MP4_BYTES` ("mp4")."""
    if fmt == "gif" and (need := gif_memory(frames, size)) > GIF_BYTES:
        raise SweepError(f"{path}: {frames} GIF frames of {size[0]} x {size[1]} px need "
                         f"{need / 1e9:.1f} GB of memory (fix: write an MP4, or fewer frames "
                         "with --fps, --from/--to, or a smaller --size)")
    if fmt == "mp4" and (need := mp4_memory(frames, size)) > MP4_BYTES:
        raise SweepError(f"{path}: an MP4 of {size[0]} x {size[1]} px needs "
                         f"{need / 1e9:.1f} GB of memory, more than {MP4_BYTES / 1e9:g} GB "
                         "(fix: a smaller --size, e.g. --size 1920x1080)")


class FrameWriter:
    """Takes (H, W, 3) uint8 frames of one size, in order."""

    def __init__(self, size: tuple[int, int]) -> None:
        self.size = size
        self.count = 0

    def write(self, rgb: np.ndarray) -> None:
        if rgb.shape != (self.size[1], self.size[0], 3):
            raise SweepError(f"a frame of {rgb.shape[1]} x {rgb.shape[0]} px in a video of "
                             f"{self.size[0]} x {self.size[1]} px (fix: report it as a bug)")
        self._write(np.ascontiguousarray(rgb, dtype=np.uint8))
        self.count += 1

    def _write(self, rgb: np.ndarray) -> None:
        raise NotImplementedError

    def finish(self) -> None:
        """Completes the file."""


class Mp4Writer(FrameWriter):
    """H.264 in an MP4 container at ``fps`` frames per second (even sizes only)."""

    def __init__(self, path: str, size: tuple[int, int], fps: float) -> None:
        super().__init__(size)
        import imageio_ffmpeg
        self._gen: Any = imageio_ffmpeg.write_frames(
            path, size, fps=fps, codec="libx264", pix_fmt_in="rgb24", pix_fmt_out="yuv420p",
            quality=7, macro_block_size=2, ffmpeg_log_level="error",
            # "-f mp4": the temporary file's name has no .mp4 ending; the encoder's threads
            # and lookahead fixed, so that its memory is the same on every machine (x264's
            # default, 1.5 threads per core and 40 frames ahead, held 283 MB for 1000 x 1000
            # px on 2 cores, 353 MB with 8 threads; render.mp4_memory)
            output_params=["-f", "mp4", "-threads", str(X264_THREADS), "-rc-lookahead",
                           str(X264_LOOKAHEAD)])
        self._gen.send(None)

    def _write(self, rgb: np.ndarray) -> None:
        self._gen.send(rgb)

    def finish(self) -> None:
        self._gen.close()


class GifWriter(FrameWriter):
    """An animated GIF, looping, each frame shown 1 / fps s (GIF counts in 10 ms units)."""

    def __init__(self, path: str, size: tuple[int, int], fps: float) -> None:
        if fps > GIF_MAX_FPS:
            raise SweepError(f"--fps {fps:g} is above {GIF_MAX_FPS:g} for a GIF, which holds "
                             "each frame a whole number of 10 ms (fix: give --fps 100 or less, "
                             "or write an MP4)")
        super().__init__(size)
        self.path, self.fps = path, fps
        self._frames: list[Any] = []

    def _write(self, rgb: np.ndarray) -> None:
        from PIL import Image
        self._frames.append(Image.fromarray(rgb).quantize(256, dither=Image.Dither.NONE))

    def finish(self) -> None:
        if not self._frames:
            return
        self._frames[0].save(self.path, format="GIF", save_all=True,
                             append_images=self._frames[1:], loop=0,
                             duration=int(round(1000.0 / self.fps)), optimize=False)


@contextmanager
def open_writer(path: str, fmt: str, size: tuple[int, int], fps: float, inputs: list[str]
                ) -> Iterator[FrameWriter]:
    """A writer of ``fmt`` ("mp4" or "gif") frames to ``path`` (never one of ``inputs``),
    through a temporary file renamed over it when the block ends without an error."""
    with replacing(path, inputs, other="--out OTHER") as tmp:
        writer: FrameWriter = (Mp4Writer(tmp, size, fps) if fmt == "mp4"
                               else GifWriter(tmp, size, fps))
        try:
            yield writer
        except BaseException:
            if isinstance(writer, Mp4Writer):
                try:
                    writer.finish()
                except Exception:  # noqa: BLE001, S110 - the error in flight is the one to report
                    pass
            raise
        writer.finish()


def output_path(recording: str, out: str | None, encoder: bool) -> tuple[str, str]:
    """The output path and format ("mp4" or "gif"): ``out``, else RUN.mp4 beside the recording
    (RUN.gif without an encoder)."""
    if out is None:
        fmt = "mp4" if encoder else "gif"
        return os.path.splitext(recording)[0] + "." + fmt, fmt
    fmt = "gif" if out.lower().endswith(".gif") else "mp4"
    if fmt == "mp4" and not out.lower().endswith(".mp4"):
        raise SweepError(f"--out {out}: names neither an MP4 nor a GIF, and the file would "
                         "hold an MP4 (fix: end the name in .mp4 or .gif)")
    if fmt == "mp4" and not encoder:
        raise SweepError(f"--out {out}: no MP4 encoder is available (imageio-ffmpeg and its "
                         "ffmpeg binary) (fix: pip install imageio-ffmpeg==0.8.1, or name the "
                         "output NAME.gif)")
    return out, fmt
