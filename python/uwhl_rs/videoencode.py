"""The restored video's encoder (docs/CLI.md "Videos"): the codecs
``--video-codec`` names and the containers each goes in, the frame sizes
they take, and :class:`Writer`, which encodes restored frames into a
temporary with the input's rate, timestamps (made increasing), other
streams, metadata, rotation and colour tags."""

from __future__ import annotations

import fractions
import os

import numpy as np

import uwhl_rs

from . import _core, video
from .errors import CommandError, ParameterError

__all__ = ["CODECS", "INPUT_CODECS", "Writer", "codec_for", "resolve_codec", "ffmpeg_text", "check_size", "extension",
           "write_error", "local_url"]

#: --video-codec: (FFmpeg encoder, pixel format for 8-bit input, for deeper input, containers it goes in)
CODECS = {
    "h264": ("libx264", "yuv420p", "yuv420p10le", (".mp4", ".mov", ".mkv", ".m4v", ".ts", ".mts", ".m2ts")),
    "hevc": ("libx265", "yuv420p", "yuv420p10le", (".mp4", ".mov", ".mkv", ".m4v", ".ts", ".mts", ".m2ts")),
    "prores": ("prores", "yuv422p10le", "yuv422p10le", (".mov",)),
    "ffv1": ("ffv1", "rgb48le", "rgb48le", (".mkv", ".mov", ".avi")),
    "mjpeg": ("mjpeg", "yuvj420p", "yuvj420p", (".mov", ".avi", ".mkv")),
}

#: FFmpeg's decoder names of codecs --video-codec input can write again
INPUT_CODECS = {"h264": "h264", "hevc": "hevc", "prores": "prores", "ffv1": "ffv1", "mjpeg": "mjpeg"}

#: --video-codec: the sides the codec's chroma subsampling needs even (width, height)
_EVEN = {"h264": (True, True), "hevc": (True, True), "prores": (True, False)}

def codec_for(choice: str, info: video.StreamInfo) -> str:
    if choice != "input":
        return choice
    got = INPUT_CODECS.get(info.codec)
    if got is None:
        raise ParameterError(f"--video-codec input: the input's codec {info.codec} cannot be written; give "
                             f"--video-codec h264, hevc, prores, ffv1 or mjpeg")
    return got


def resolve_codec(choice: str, path: str) -> str:
    """``choice`` with "input" replaced by the codec of the video at local
    ``path`` when it is one that can be written (so that its output names
    are claimed with that codec's container); ``choice`` unchanged when the
    file cannot be read (:func:`restore_video` then says why)."""
    if choice != "input":
        return choice
    try:
        return codec_for(choice, video.probe(path, transfer="bt709", rotation=False))
    except (ValueError, OSError):
        return choice


def local_url(path: str) -> str:
    """What FFmpeg is given to write the local file at ``path``: its
    absolute path behind ``file:``. A bare name is read as a URL, so an
    output folder called ``tcp:`` would send the video to a socket,
    ``file:zz`` would write it to ``zz``, ``dive:2`` would be an unknown
    protocol; and PyAV opens an output with ``avio_open`` without the
    options, so a ``protocol_whitelist`` there would not be honoured."""
    return "file:" + os.path.abspath(path)


def ffmpeg_text(e: BaseException) -> str:
    """FFmpeg's reason without the file name it names (a temporary's, which means nothing to the user)."""
    why = getattr(e, "strerror", None) or str(e) or type(e).__name__
    log = getattr(e, "log", None)
    if isinstance(log, tuple) and len(log) == 3 and log[2]:
        why += f" ({str(log[2]).strip()})"
    return why


def write_error(shown: str, e: OSError, where: str = "") -> CommandError:
    """A failed write of the output ``shown`` (a full disk, a file size
    limit), worded as the photo path words one: ``cannot write OUT: REASON
    (os error N)``, kind write_failed (exit 5). It names the output the user
    asked for, not the temporary it was being written to, and the reason
    without FFmpeg's file name; an error that already says ``cannot write``
    (the core's, which names the output) keeps its words. ``where``, if
    given, follows the output's name (``(frame 12)``)."""
    text = getattr(e, "strerror", None) or str(e) or type(e).__name__
    if text.startswith("cannot write "):
        return CommandError(text, "write_failed")
    why = ffmpeg_text(e)
    code = getattr(e, "errno", None)
    # FFmpeg's own codes (AVERROR_INVALIDDATA, ...) are not the system's: only an OSError's is said
    if isinstance(e, OSError) and isinstance(code, int) and code > 0 and f"(os error {code})" not in why:
        why += f" (os error {code})"
    return CommandError(f"cannot write {shown}{where}: {why}", "write_failed")


def check_size(codec: str, size: tuple[int, int], label: str, max_side) -> None:
    """ParameterError when ``codec`` cannot hold frames of ``size`` (H, W):
    4:2:0 needs an even width and height, 4:2:2 an even width."""
    need_w, need_h = _EVEN.get(codec, (False, False))
    h, w = size
    if (need_w and w % 2) or (need_h and h % 2):
        sub, sides = ("4:2:2", "an even width") if not need_h else ("4:2:0", "an even width and height")
        raise ParameterError(f"{label}: the restored frames are {w}x{h} pixels; {codec} is written {sub}, which "
                             f"needs {sides}: give --video-codec ffv1 or mjpeg (any size)"
                             + (", or another --max-side" if max_side else ""))


def extension(in_path: str, codec: str) -> str:
    """The restored video's extension: the input's when its container takes the codec, else the codec's first."""
    ext = os.path.splitext(in_path)[1].lower()
    allowed = CODECS[codec][3]
    return ext if ext in allowed else allowed[0]


class Writer:
    """The restored video, encoded into a temporary as frames come;
    ``shown``, the output the temporary becomes, is what a failed write
    names (the temporary's name means nothing to the user)."""

    def __init__(self, tmp: str, ext: str, codec: str, info: video.StreamInfo, size: tuple[int, int],
                 crf: int, src, shown: str | None = None):
        import av

        encoder, pix8, pix_deep, _ = CODECS[codec]
        self.av = av
        self.shown = shown or "the restored video"
        self.pix = pix_deep if info.bits > 8 else pix8
        self.bits = 16
        self.transfer = info.transfer
        #: streams dropped part way (a packet the container refused), and frames whose timestamp was not increasing
        self.notes: list[str] = []
        self.retimed = 0
        #: frames of another size than the stream's first (a stream may change size mid-way):
        #: how many, and the first as (written index, height, width)
        self.size = (int(size[0]), int(size[1]))
        self.rescaled = 0
        self.first_rescaled: tuple[int, int, int] | None = None
        fmt = {".mkv": "matroska", ".ts": "mpegts", ".mts": "mpegts", ".m2ts": "mpegts", ".m4v": "mp4"}.get(ext)
        try:
            self.out = av.open(local_url(tmp), "w", format=fmt or ext.lstrip("."))
        except (av.FFmpegError, ValueError) as e:
            raise CommandError(f"cannot write a {ext} video: {ffmpeg_text(e)}", "write_failed") from None
        try:
            vs = src.streams.video[0]
            rate = info.rate or 30
            st = self.out.add_stream(encoder, rate=rate)
            st.width, st.height = size[1], size[0]
            st.pix_fmt = self.pix
            st.time_base = vs.time_base
            st.codec_context.time_base = vs.time_base
            # a frame's length in the stream's time base: the step given to a timestamp that does not increase
            tb = vs.time_base or fractions.Fraction(1, 90000)
            self.step = max(1, int(round(1 / (float(rate) * float(tb)))))
            if codec in ("h264", "hevc"):
                st.options = {"crf": str(crf), "preset": "medium"}
            if codec == "hevc":
                # x265 prints its banner and statistics on stderr, which is for the errors
                st.options = {**st.options, "x265-params": "log-level=error"}
            if info.rotation:
                # a phone's upright video stays upright: the display matrix is the input's
                st.set_display_rotation(info.rotation if info.rotation <= 180 else info.rotation - 360)
            cc = st.codec_context
            # the tags of what is written: the input's primaries, the curve
            # the frames were encoded with, BT.709's matrix (RGB's for
            # FFV1), limited range (full for motion JPEG and RGB)
            from av.video.reformatter import ColorPrimaries, ColorRange, Colorspace, ColorTrc

            trc = {"bt709": ColorTrc.BT709, "srgb": ColorTrc.IEC61966_2_1, "gamma22": ColorTrc.GAMMA22,
                   "gamma28": ColorTrc.GAMMA28, "linear": ColorTrc.LINEAR}[info.transfer]
            prim = src.streams.video[0].codec_context.color_primaries
            cc.color_primaries = int(prim) if int(prim or 2) != 2 else int(ColorPrimaries.BT709)
            cc.color_trc = int(trc)
            self.rgb = self.pix.startswith("rgb")
            # FFmpeg's AVCOL_SPC_RGB is 0 (H.273's identity matrix, "gbr"), which PyAV's Colorspace does not name
            cc.colorspace = 0 if self.rgb else int(Colorspace.ITU709)
            self.range = ColorRange.JPEG if self.pix.startswith("yuvj") or self.rgb else ColorRange.MPEG
            cc.color_range = int(self.range)
            self.video = st
            self.audio = {}
            for other in src.streams:
                if other.index == vs.index or other.type not in ("audio", "subtitle"):
                    continue
                try:
                    self.audio[other.index] = self.out.add_stream_from_template(other)
                except (av.FFmpegError, ValueError):
                    continue  # a stream the container cannot hold (named in the sidecar's notes)
            for k, v in src.metadata.items():
                if k not in ("encoder", "major_brand", "minor_version", "compatible_brands"):
                    self.out.metadata[k] = v
            self.out.metadata["comment"] = f"restored by uwhl_rs {uwhl_rs.__version__} (haze-lines, sequence mode)"
            # the encoder is opened now, so that one that refuses the size or format says so before any frame
            st.codec_context.open()
        except av.FFmpegError as e:
            self.out.close()
            raise CommandError(f"FFmpeg cannot write {size[1]}x{size[0]} frames as {codec} ({encoder}) in a {ext} "
                               f"file: {ffmpeg_text(e)}", "unreadable_input") from None
        except BaseException:
            self.out.close()
            raise
        self.frames = 0
        self.last_pts = None

    def copy(self, packet) -> None:
        """A packet of another stream, remuxed unchanged; a stream whose
        packet the container refuses (its timestamps) is dropped from there
        on, with a note, and the video goes on."""
        st = self.audio.get(packet.stream.index)
        if st is None or packet.dts is None:
            return
        index = packet.stream.index
        packet.stream = st
        try:
            self.out.mux(packet)
        except self.av.FFmpegError as e:
            del self.audio[index]
            self.notes.append(f"stream #{index} ({st.type}) copied up to {float(packet.dts * st.time_base):.3f} s only: "
                              f"the container refused a packet ({ffmpeg_text(e)})")

    def write(self, image: np.ndarray, pts: int | None) -> None:
        """Encode one restored frame (linear float32 (H, W, 3)) at ``pts``
        (made increasing); a failed write is write_failed naming the output."""
        codes = _core.frame_from_linear(np.ascontiguousarray(image, dtype=np.float32), self.transfer, 16)
        f = self.av.VideoFrame.from_ndarray(codes, format="rgb48le")
        if image.shape[:2] != self.size:
            # a video stream holds one frame size: the encoder would scale this frame to it anyway;
            # doing it here, and counting it, lets the sidecar say so
            if self.first_rescaled is None:
                self.first_rescaled = (self.frames, int(image.shape[0]), int(image.shape[1]))
            self.rescaled += 1
            f = f.reformat(width=self.size[1], height=self.size[0])
        if not self.rgb:
            f = f.reformat(format=self.pix, dst_colorspace="ITU709", dst_color_range=self.range)
        if pts is None or (self.last_pts is not None and pts <= self.last_pts):
            # a container takes increasing timestamps only: a missing, repeated or earlier one
            # becomes a frame after the previous (counted in the sidecar's notes)
            pts = 0 if self.last_pts is None else self.last_pts + self.step
            self.retimed += 1
        f.pts = pts
        self.last_pts = pts
        try:
            for p in self.video.encode(f):
                self.out.mux(p)
        except (self.av.FFmpegError, OSError) as e:
            raise write_error(self.shown, e, f" (frame {self.frames})") from None
        self.frames += 1

    def close(self, flush: bool = True) -> None:
        """Finish the video: the encoder's last frames (``flush``) and the
        container's trailer, whose write is where a full disk is often
        first seen (FFmpeg buffers the packets); either failing is
        write_failed naming the output. ``flush`` False abandons the video
        after another error: the container's own failure to close is then
        dropped, so that error is the one reported."""
        try:
            if flush:
                for p in self.video.encode():
                    self.out.mux(p)
        except (self.av.FFmpegError, OSError) as e:
            self._close_quietly()
            raise write_error(self.shown, e) from None
        except BaseException:
            self._close_quietly()
            raise
        try:
            self.out.close()
        except (self.av.FFmpegError, OSError) as e:
            if flush:
                raise write_error(self.shown, e) from None

    def _close_quietly(self) -> None:
        try:
            self.out.close()
        except (self.av.FFmpegError, OSError):
            pass
