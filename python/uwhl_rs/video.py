"""Videos: frames read through FFmpeg (PyAV), restored as one sequence
(:class:`uwhl_rs.Sequence`, METHOD §10: the water type and A estimated on
the first frame, on a schedule, at cuts and drifts, A smoothed between
estimates), and frames out (docs/API.md "Videos").

>>> for frame in restore_frames("dive_017.mp4"):     # doctest: +SKIP
...     frame.image          # float32 (H, W, 3), linear light, as restore() gives it
...     frame.decision       # "first", "scheduled", "cut", "drift" or "reused"

A frame's samples are decoded to 16-bit RGB by FFmpeg with the stream's
own matrix and range (BT.709 when an HD stream does not say, BT.601 below
720 lines), then made linear by undoing the stream's transfer curve
(``_core.frame_to_linear``: BT.709 when the stream does not say), so 8-
and 10-bit streams are read without banding and the model of METHOD §0
holds. The files a video becomes are written by :mod:`uwhl_rs.videofiles`.

PyAV is a dependency of the package: its wheels carry their own FFmpeg
(H.264, H.265, ProRes, MJPEG, FFV1, VP9 and more; libx264 and libx265 to
write), so nothing has to be installed on the system.
"""

from __future__ import annotations

import fractions
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

import uwhl_rs

from . import _core
from .files import max_side_factor
from .errors import ImageReadError, ParameterError

__all__ = ["VIDEO_EXTENSIONS", "StreamInfo", "Frame", "RestoredFrame", "is_video", "probe", "read_frames",
           "restore_frames", "refresh_for", "display_angle", "display_rotation", "quarter_turns"]

#: file extensions read as videos (lower case, with the dot)
VIDEO_EXTENSIONS = frozenset("." + e for e in _core.VIDEO_EXTENSIONS)

#: H.273 colour matrices (FFmpeg's colorspace codes) -> swscale's names
_MATRICES = {1: "ITU709", 4: "FCC", 5: "ITU601", 6: "SMPTE170M", 7: "SMPTE240M", 9: "BT2020", 10: "BT2020"}


def is_video(path: str | os.PathLike) -> bool:
    """Whether ``path``'s extension is a video's."""
    return os.path.splitext(os.fspath(path))[1].lower() in VIDEO_EXTENSIONS


def _av():
    try:
        import av
    except ImportError:  # pragma: no cover - a dependency of the package
        raise ImageReadError("reading videos needs PyAV (pip install av)") from None
    return av


def _enum_name(enum_cls, value) -> str:
    try:
        return enum_cls(int(value)).name.lower()
    except (ValueError, TypeError):
        return "unspecified"


@dataclass
class StreamInfo:
    """A video file's first video stream, as FFmpeg reports it."""

    path: str
    container: str
    codec: str
    width: int
    height: int
    #: frames a second (the stream's average rate), None when unknown
    rate: fractions.Fraction | None
    time_base: fractions.Fraction
    #: the frame count the container states (0 or None: unknown)
    frames: int | None
    #: seconds, None when unknown
    duration: float | None
    pix_fmt: str
    #: bits a sample of the coded frames
    bits: int
    #: the stream's tags (H.273 names as FFmpeg gives them)
    transfer_tag: str
    primaries_tag: str
    matrix_tag: str
    range_tag: str
    #: the curve its samples are read with (``--transfer``'s names) and why
    transfer: str
    transfer_from: str
    #: the matrix used to convert YUV to RGB, and why
    matrix: str
    matrix_from: str
    #: the audio and other streams (kept in a restored video when the container takes them)
    others: list = field(default_factory=list)
    metadata: dict = field(default_factory=dict)
    #: where the stream ends, in seconds of its timestamps (None: unknown)
    end: float | None = None
    #: the counter-clockwise rotation of its display matrix, degrees (0, 90, 180, 270; :func:`probe`)
    rotation: int = 0
    #: of ``frames``, those the container's edit list leaves out (an MP4 or MOV trimmed without
    #: re-encoding keeps the samples before the cut and marks them discarded in its index)
    edited_out: int = 0

    @property
    def frames_shown(self) -> int | None:
        """The frames the stream gives when decoded: the stated count less
        those its edit list leaves out (None: the container does not say)."""
        if not self.frames:
            return None
        return max(self.frames - self.edited_out, 0) or None

    def to_dict(self) -> dict:
        """The sidecar's ``video.stream``."""
        d = {k: getattr(self, k) for k in ("container", "codec", "width", "height", "frames", "duration", "pix_fmt",
                                            "bits", "transfer_tag", "primaries_tag", "matrix_tag", "range_tag",
                                            "transfer", "transfer_from", "matrix", "matrix_from")}
        # FFmpeg's sign: -90 is a phone held upright (turned a quarter clockwise to show)
        d["rotation"] = -90 if self.rotation == 270 else self.rotation
        d["frames_edited_out"] = int(self.edited_out)
        d["rate"] = None if self.rate is None else float(self.rate)
        d["rate_fraction"] = None if self.rate is None else f"{self.rate.numerator}/{self.rate.denominator}"
        d["time_base"] = f"{self.time_base.numerator}/{self.time_base.denominator}"
        d["other_streams"] = list(self.others)
        return d


#: the top-level boxes an MP4 or MOV (ISO BMFF, QuickTime) begins with
_BMFF_FIRST = frozenset({b"ftyp", b"moov", b"mdat", b"free", b"skip", b"wide", b"pnot", b"styp"})


def _index_missing(path: str) -> bool:
    """Whether the file at ``path`` is built as an MP4 or MOV (ISO BMFF
    boxes from its first byte) whose top level holds no ``moov``, the
    index: what a recording cut short leaves when its index was to be
    written at the end. False for anything else, whatever its name says."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            end = f.tell()
            pos, first, media = 0, True, False
            # a hostile file of empty boxes ends the walk: at most this many are read
            for _ in range(100_000):
                if pos + 8 > end:
                    break
                f.seek(pos)
                head = f.read(16)
                size, kind = int.from_bytes(head[:4], "big"), head[4:8]
                if first and kind not in _BMFF_FIRST:
                    return False
                first = False
                if kind == b"moov":
                    return False
                # a recording's file type or its media: eight bytes that merely look like a box are not one
                media = media or kind in (b"ftyp", b"mdat")
                if size == 1 and len(head) == 16:
                    size = int.from_bytes(head[8:16], "big")
                elif size == 0:
                    break  # the last box runs to the end of the file
                if size < 8:
                    return False  # not a box: not BMFF after all
                pos += size
            return media
    except OSError:
        return False


#: the containers a video is read from: FFmpeg's demuxers that hold their
#: own streams. Playlists and lists of other files (concat, hls, image2's
#: patterns) would open files, FIFOs or sockets the user never named.
FORMATS = "mov,mp4,m4a,3gp,3g2,mj2,matroska,webm,avi,mpegts,mxf,mpeg,asf,flv,ogg,h264,hevc,mjpeg"


def _av_open(path: str):
    """FFmpeg's reader of ``path`` itself: by its absolute path (a bare
    ``file:x.mp4``, ``concat:a|b`` or ``unix:s`` would be a protocol), with
    the file protocol only and the container formats of :data:`FORMATS`."""
    av = _av()
    return av.open(os.path.abspath(path), metadata_errors="replace",
                   options={"protocol_whitelist": "file", "format_whitelist": FORMATS})


def _open(path: str):
    """The container at ``path`` opened for reading, with an error naming
    what is wrong (not a file, an empty file, not a video FFmpeg reads)."""
    av = _av()
    if not os.path.isfile(path):
        why = "no such file or folder" if not os.path.exists(path) else "not a regular file (not opened)"
        raise ImageReadError(f"{path}: {why}")
    try:
        empty = os.path.getsize(path) == 0
    except OSError as e:
        raise ImageReadError(f"{path}: cannot open ({e.strerror or e})") from None
    if empty:
        # the words of a photo's reader (and uwhl-rs's) for an empty file
        raise ImageReadError(f"{path}: empty file")
    try:
        return _av_open(path)
    except av.FFmpegError as e:
        # an MP4 or MOV written to the end keeps its index there: cut short, it is unreadable as a whole; the
        # hint is for such a file only (its boxes say so), not for any file called .mp4
        hint = "; it is an MP4 or MOV without its index (moov), which is written at the end: a recording cut " \
            "short cannot be read at all" if _index_missing(path) else ""
        why = getattr(e, "strerror", None) or str(e) or type(e).__name__
        raise ImageReadError(f"{path}: not a video FFmpeg can read ({why}){hint}") from None


def _info(path: str, container, transfer: str | None) -> StreamInfo:
    if not container.streams.video:
        raise ImageReadError(f"{path}: the file holds no video stream")
    vs = container.streams.video[0]
    cc = vs.codec_context
    if cc.codec is None or not getattr(cc.codec, "name", None):
        raise ImageReadError(f"{path}: the video stream's codec is unknown to FFmpeg")
    if cc.width <= 0 or cc.height <= 0:
        # FFmpeg leaves the size 0x0 when the header's is absurd or missing (cut short before the first frame)
        raise ImageReadError(f"{path}: the video stream states no usable frame size ({cc.width}x{cc.height}): "
                             "cut short or corrupt?")
    if cc.width < 4 or cc.height < 4:
        raise ImageReadError(f"{path}: the video is {cc.width}x{cc.height} pixels; at least 4x4 is restored")
    from av.video.reformatter import ColorPrimaries, ColorRange, Colorspace, ColorTrc  # noqa: F401

    trc_tag = _enum_name(ColorTrc, cc.color_trc)
    matrix_tag = _enum_name(Colorspace, cc.colorspace)
    if transfer is not None:
        curve, why = transfer, "--transfer"
    else:
        try:
            curve = _core.transfer_of_tag(trc_tag)
        except ValueError as e:
            raise ImageReadError(f"{path}: {e}") from None
        why = "the stream's tag"
        if curve is None:
            curve, why = "bt709", "the stream does not say: BT.709, the curve of video cameras"
    code = int(cc.colorspace or 2)
    if code in _MATRICES:
        matrix, matrix_from = _MATRICES[code], "the stream's tag"
    else:
        matrix = "ITU709" if cc.height >= 720 else "ITU601"
        matrix_from = f"the stream does not say: {'BT.709 (HD)' if cc.height >= 720 else 'BT.601 (SD)'}"
    bits = 8
    fmt = cc.format
    if fmt is not None and fmt.components:
        bits = max(int(c.bits) for c in fmt.components)
    rate = vs.average_rate or vs.guessed_rate or vs.base_rate
    others = []
    for s in container.streams:
        if s.index == vs.index:
            continue
        name = getattr(getattr(s, "codec_context", None), "name", None) or "unknown"
        others.append({"index": int(s.index), "type": s.type, "codec": name})
    duration, end = _stream_span(container, vs)
    edited_out = _edited_out(vs)
    return StreamInfo(
        path=path, container=container.format.name, codec=cc.codec.name, width=int(cc.width), height=int(cc.height),
        rate=fractions.Fraction(rate) if rate else None,
        time_base=fractions.Fraction(vs.time_base) if vs.time_base else fractions.Fraction(1, 90000),
        frames=int(vs.frames) or None, duration=duration, pix_fmt=str(cc.pix_fmt), bits=bits,
        transfer_tag=trc_tag, primaries_tag=_enum_name(ColorPrimaries, cc.color_primaries), matrix_tag=matrix_tag,
        range_tag=_enum_name(ColorRange, cc.color_range), transfer=curve, transfer_from=why, matrix=matrix,
        matrix_from=matrix_from, others=others, metadata=dict(container.metadata), end=end, edited_out=edited_out,
    )


def _edited_out(vs) -> int:
    """The samples of the stream's index that the demuxer marks discarded:
    those an MP4 or MOV edit list leaves out (before a trim's start, after
    its end), which the stated frame count includes and the decoder never
    gives. 0 for a container without such an index (Matroska's cues, a
    transport stream's none)."""
    try:
        entries = vs.index_entries
        return sum(1 for e in entries if e.is_discard)
    except (AttributeError, TypeError, ValueError, IndexError):
        return 0  # a PyAV without index entries: the stated count stands


def _stream_span(container, vs) -> tuple[float | None, float | None]:
    """(duration, end) of the video stream in seconds, each None when the
    file does not say: its own duration (the header's, or Matroska's
    DURATION tag, which is where the stream ends); the container's only
    when the video is its one stream (else it may be the sound's, longer),
    Matroska's counted from time 0 (a recording whose clock starts at 10 h
    lasts its duration minus 10 h)."""
    av = _av()
    tb = vs.time_base
    start = float(vs.start_time * tb) if vs.start_time is not None and tb else 0.0
    if vs.duration is not None and tb:
        d = float(vs.duration * tb)
        return d, start + d
    tag = (vs.metadata or {}).get("DURATION")
    if isinstance(tag, str):
        try:
            h, m, sec = tag.strip().split(":")
            end = int(h) * 3600 + int(m) * 60 + float(sec)
            if math.isfinite(end) and end > 0:
                return max(end - start, 0.0), end
        except ValueError:
            pass
    if container.duration is not None and len(container.streams) == 1:
        d = container.duration / av.time_base
        if "matroska" in (container.format.name or ""):
            # a Matroska segment's duration runs from time 0, wherever its timestamps start: it is the end
            return max(d - start, 0.0), d
        return d, start + d
    return None, None


def _angle_of(frame) -> float:
    """The counter-clockwise rotation (degrees, as FFmpeg reports it) of a
    decoded frame's display matrix; 0 without one."""
    try:
        r = float(getattr(frame, "rotation", 0) or 0)
    except (TypeError, ValueError, OverflowError):
        return 0.0
    return r if math.isfinite(r) else 0.0


def display_angle(path: str) -> float:
    """The counter-clockwise rotation (degrees, as FFmpeg reports it) of
    the stream's display matrix (a phone's), read from its first frame; 0
    when it has none or the frame cannot be decoded. It decodes a whole
    frame: a caller that plans memory reads the size from :func:`probe`
    (``rotation=False``) and checks it first."""
    av = _av()
    try:
        with _av_open(path) as c:
            for frame in c.decode(c.streams.video[0]):
                return _angle_of(frame)
    except (av.FFmpegError, EOFError, ValueError, OverflowError, IndexError):
        pass
    return 0.0


def quarter_turns(angle: float) -> int | None:
    """``angle`` (degrees) as a rotation a player applies by quarter turns
    (0, 90, 180, 270), or None when it is not a multiple of 90 (half a
    degree either way is the fixed-point matrix's rounding)."""
    q = round(angle / 90.0)
    return int(q) * 90 % 360 if abs(angle - 90.0 * q) < 0.5 else None


def display_rotation(path: str) -> int:
    """The counter-clockwise rotation (0, 90, 180, 270) a player applies to
    the stream's frames (:func:`display_angle`); 0 also for a matrix that is
    not a multiple of 90 degrees, which is not applied (:func:`quarter_turns`)."""
    return quarter_turns(display_angle(path)) or 0


def probe(path: str | os.PathLike, *, transfer: str | None = None, rotation: bool = True) -> StreamInfo:
    """The first video stream of the file at ``path`` (ImageReadError when
    it is not a video FFmpeg reads, or its transfer curve is not read and
    ``transfer`` does not say one). The headers only, unless ``rotation``:
    then the first frame is decoded for its display matrix (:func:`display_rotation`),
    and ``info.rotation`` is 0 without it."""
    path = os.fspath(path)
    with _open(path) as c:
        info = _info(path, c, transfer)
    if rotation:
        info.rotation = display_rotation(path)
    return info


@dataclass
class Frame:
    """One decoded frame."""

    #: its place in the stream, from 0
    index: int
    #: its timestamp in the stream's time base, and in seconds (None when the stream has none)
    pts: int | None
    time: float | None
    #: float32 (H, W, 3), linear light
    image: np.ndarray


class FrameReader:
    """The frames of a video, decoded in order (:func:`read_frames`).
    Iterating stops at the end of the stream, or at the first frame FFmpeg
    cannot decode: :attr:`stopped` then says where and why (a truncated or
    corrupt file restores the frames before it)."""

    def __init__(self, path: str, *, transfer: str | None = None, every: int = 1, max_side: int | None = None,
                 rotation: int = 0):
        self.path = path
        self._c = _open(path)
        try:
            self.info = _info(path, self._c, transfer)
        except BaseException:
            self._c.close()
            raise
        self.every = max(1, int(every))
        self.max_side = max_side
        #: quarter turns counter-clockwise (np.rot90) given to each frame, so that it is shown as a player shows it
        self.turns = (int(rotation) // 90) % 4
        #: the display matrix's angle on the first frame decoded (:func:`display_angle`), None before it
        self.angle: float | None = None
        #: None, or where decoding stopped: {"frame": k, "time": seconds or None, "error": text}
        self.stopped: dict | None = None
        #: frames decoded (read, whether or not ``every`` kept them)
        self.decoded = 0
        #: called with every packet of the other streams, in file order
        #: (a restored video copies them); None: they are not read
        self.on_packet = None
        #: the linear image of the last frame given
        self.last_input: np.ndarray | None = None

    def close(self) -> None:
        self._c.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _linear(self, frame) -> np.ndarray:
        from av.video.reformatter import ColorRange

        rng = frame.color_range
        if int(rng or 0) == 0:
            rng = ColorRange.JPEG if str(frame.format.name).startswith("yuvj") else ColorRange.MPEG
        rgb = frame.to_ndarray(format="rgb48le", src_colorspace=self.info.matrix, src_color_range=rng)
        img = _core.frame_to_linear(np.ascontiguousarray(rgb), self.info.transfer)
        s = max_side_factor(*img.shape[:2], self.max_side)
        img = _core._downscale(img, s) if s > 1 else img
        return np.ascontiguousarray(np.rot90(img, self.turns)) if self.turns else img

    def __iter__(self) -> Iterator[Frame]:
        av = _av()
        vs = self._c.streams.video[0]
        vs.thread_type = "AUTO"
        tb = vs.time_base
        streams = [vs] + ([s for s in self._c.streams if s.index != vs.index] if self.on_packet else [])
        k = 0
        last_t = None
        try:
            for packet in self._c.demux(*streams):
                if packet.stream.index != vs.index:
                    self.on_packet(packet)
                    continue
                for frame in packet.decode():
                    self.decoded = k + 1
                    if self.angle is None:
                        self.angle = _angle_of(frame)
                    if frame.pts is not None and tb is not None:
                        t_k = float(frame.pts * tb)
                        last_t = t_k if last_t is None else max(last_t, t_k)
                    if frame.width * frame.height > self.info.width * self.info.height:
                        # the limits (--max-pixels, --max-memory) were checked against the size the
                        # stream states; a larger frame part way would go past them: decoding stops here
                        self.stopped = {"frame": k, "time": self._time_of(k),
                                        "error": f"frame {k} is {frame.width}x{frame.height}, larger than the "
                                                 f"{self.info.width}x{self.info.height} the stream states and its "
                                                 f"memory was planned for"}
                        return
                    if k % self.every == 0:
                        pts = frame.pts
                        t = float(pts * tb) if pts is not None and tb is not None else None
                        self.last_input = self._linear(frame)
                        yield Frame(k, pts, t, self.last_input)
                    k += 1
        except (av.FFmpegError, EOFError) as e:
            self.stopped = {"frame": k, "time": self._time_of(k), "error": f"{type(e).__name__}: {e}"[:500]}
            return
        # a file cut short may end without an error: fewer frames than its header states (less those
        # its edit list leaves out, which the decoder never gives), or (no count stated) its frames
        # end well before the time the stream states it ends
        expected = self.info.frames_shown
        if expected and k < expected - 1:
            trim = f" ({self.info.edited_out} of them left out by its edit list)" if self.info.edited_out else ""
            self.stopped = {"frame": k, "time": self._time_of(k),
                            "error": f"the file ends after {k} frames; its header states {self.info.frames}{trim}: "
                                     "cut short?"}
        elif not expected and self.info.end and self.info.rate:
            step = 1.0 / float(self.info.rate)
            reached = (last_t + step) if last_t is not None else k * step
            # two frames of slack: the stated end is rounded, and a variable rate's last frame may last longer
            if reached < self.info.end - 2.5 * step:
                self.stopped = {"frame": k, "time": self._time_of(k),
                                "error": f"the file ends after {k} frames, at {reached:.3f} s; the stream states "
                                         f"it ends at {self.info.end:.3f} s: cut short?"}

    def _time_of(self, k: int) -> float | None:
        return round(k / float(self.info.rate), 3) if k > 0 and self.info.rate else None


def read_frames(path: str | os.PathLike, *, transfer: str | None = None, every: int = 1,
                max_side: int | None = None, rotation: int = 0) -> FrameReader:
    """The frames of the video at ``path`` as linear light (a
    :class:`FrameReader`: iterate it; use it in a ``with`` block to close
    the file). ``transfer`` overrides the stream's curve (``--transfer``'s
    names), ``every`` keeps every N-th frame, ``max_side`` block-averages
    each frame so its longer side is at most N, ``rotation`` (degrees
    counter-clockwise, a multiple of 90: :func:`display_rotation`) turns
    each frame as a player shows it."""
    return FrameReader(os.fspath(path), transfer=transfer, every=every, max_side=max_side, rotation=rotation)


@dataclass
class RestoredFrame:
    """One restored frame of :func:`restore_frames`."""

    index: int
    pts: int | None
    time: float | None
    #: the restored frame, float32 (H, W, 3), linear light (``restoration.image``)
    image: np.ndarray
    #: the whole :class:`uwhl_rs.Restoration`
    restoration: object
    #: why it estimated or reused: "first", "scheduled", "cut", "drift", "reused"
    decision: str
    #: its colour change from the previous frame (0-1, METHOD §10)
    change: float
    #: why the frame was not restored (decision "unrestored": ``image`` is the frame as it came in,
    #: ``restoration`` None), else None
    error: str | None = None


def refresh_for(rate, every: int = 1) -> int:
    """Restored frames between scheduled estimates when none is given: about
    a second of video (30 when the rate is unknown)."""
    if not rate:
        return 30
    return max(1, int(round(float(rate) / max(1, every))))


def restore_frames(video, *, every: int = 1, refresh_every: int | None = None,
                   scene_cut: float = _core.VIDEO_SCENE_CUT, smoothing: float = _core.VIDEO_SMOOTHING,
                   reuse_water_mask: bool = False, transfer: str | None = None, max_side: int | None = None,
                   unrestored: str = "raise", **method) -> Iterator[RestoredFrame]:
    """Restore a video's frames in order as one sequence (METHOD §10).

    ``video``: a path, a :class:`FrameReader` (whose ``stopped`` then says
    whether the file ended early), or an iterable of linear float32 frames
    (numpy (H, W, 3) arrays or :class:`Frame`). The water type and A are estimated
    on the first frame, every ``refresh_every`` restored frames (default:
    about a second of the video's frames, 30 for frames without a rate),
    when a frame's colours change from the previous frame's by more than
    ``scene_cut`` (a cut: estimated afresh) or drift by as much from the
    last estimate's, and a scheduled or drift estimate moves A only
    ``smoothing`` of the way (docs/API.md "Videos"). ``every`` restores
    every N-th frame only; ``transfer`` and ``max_side`` as in
    :func:`read_frames`; ``method``: the keywords of :func:`uwhl_rs.restore`.

    A frame the method cannot restore (a black or flat frame: a fade, a
    flash; nothing to restore) raises ImageReadError naming the frame, or
    with ``unrestored="input"`` is yielded as it came in (decision
    "unrestored", ``restoration`` None, ``error`` the reason) and the
    sequence goes on from the frames before it.

    Yields :class:`RestoredFrame`. A video that stops decoding part way ends
    the iteration; pass a :func:`read_frames` reader to read its
    ``stopped`` (as :func:`uwhl_rs.videofiles.restore_video` does).
    """
    for name, v, ok in (("scene_cut", scene_cut, 0 <= scene_cut <= 1), ("smoothing", smoothing, 0 < smoothing <= 1)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not ok:
            raise ParameterError(f"{name} must be a number in {'[0, 1]' if name == 'scene_cut' else '(0, 1]'}; got {v!r}")
    reader = None
    if isinstance(video, FrameReader):
        frames, rate = iter(video), video.info.rate
    elif isinstance(video, (str, os.PathLike)):
        reader = read_frames(video, transfer=transfer, every=every, max_side=max_side)
        frames = iter(reader)
        rate = reader.info.rate
    else:
        frames = (f if isinstance(f, Frame) else Frame(k, None, None, np.asarray(f, dtype=np.float32))
                  for k, f in enumerate(video))
        rate = None
    if unrestored not in ("raise", "input"):
        raise ParameterError(f'unrestored must be "raise" or "input"; got {unrestored!r}')
    n = refresh_for(rate, every) if refresh_every is None else int(refresh_every)
    seq = uwhl_rs.Sequence(refresh_every=n, reuse_water_mask=reuse_water_mask, scene_cut=scene_cut,
                           smoothing=smoothing, **method)
    try:
        for f in frames:
            try:
                res = seq.restore(f.image)
            except _core.ImageError as e:
                # the sequence is left as it was: the next frame compares with the one before this
                if unrestored == "raise":
                    at = "" if f.time is None else f" ({f.time:.3f} s)"
                    raise ImageReadError(f"frame {f.index}{at}: {e}") from None
                yield RestoredFrame(f.index, f.pts, f.time, f.image, None, "unrestored", 0.0, str(e))
                continue
            decision, change = seq.last_decision
            yield RestoredFrame(f.index, f.pts, f.time, res.image, res, decision, float(change))
    finally:
        if reader is not None:
            reader.close()
