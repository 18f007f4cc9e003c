"""A video's files in an output folder (docs/OUTPUTS.md "Videos").

``uwhl restore dive.mp4 -o out`` writes ``out/dive.mp4`` (the restored
video: same size, rate and timestamps, the other streams and the
container's metadata copied, colour tags written), ``out/dive_strip.jpg``
(frames across the video, input above restored) and ``out/dive.json``
(the video's sidecar, written last: the stream, the estimates over time,
every re-estimation and why). With ``--every N`` the restored video is
replaced by every N-th frame as a photo, each with its maps and sidecar
(``dive_00h01m02s345.jpg``: its time in the video), the video's sidecar
listing them.

Nothing that looks complete is left by an interrupted run: the video and
the strip are written to temporaries of the output folder and put in
place with the sidecar last (``_core.Claim``, as a photo's outputs); a
rerun restores the video again from the start (its stills already
written are kept and not written again). A video that stops decoding part
way is restored up to there; its sidecar says where it stopped and why.
"""

from __future__ import annotations

import fractions
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

import uwhl_rs

from . import _core, files, video
from .errors import CommandError, ImageTooLargeError, ParameterError
from .sidecars import display

__all__ = ["VideoResult", "video_suffixes", "restore_video", "still_name", "resolve_codec", "CODECS"]

#: --video-codec: (FFmpeg encoder, pixel format for 8-bit input, for deeper input, containers it goes in)
CODECS = {
    "h264": ("libx264", "yuv420p", "yuv420p10le", (".mp4", ".mov", ".mkv", ".m4v", ".ts", ".mts", ".m2ts")),
    "hevc": ("libx265", "yuv420p", "yuv420p10le", (".mp4", ".mov", ".mkv", ".m4v", ".ts", ".mts", ".m2ts")),
    "prores": ("prores", "yuv422p10le", "yuv422p10le", (".mov",)),
    "ffv1": ("ffv1", "rgb48le", "rgb48le", (".mkv", ".mov", ".avi")),
    "mjpeg": ("mjpeg", "yuvj420p", "yuvj420p", (".mov", ".avi", ".mkv")),
}

#: FFmpeg's decoder names of codecs --video-codec input can write again
_INPUT_CODECS = {"h264": "h264", "hevc": "hevc", "prores": "prores", "ffv1": "ffv1", "mjpeg": "mjpeg"}

#: frames of the strip
_STRIP_FRAMES = 8
#: the longer side of a strip cell
_STRIP_CELL = 240

#: --video-codec: the sides the codec's chroma subsampling needs even (width, height)
_EVEN = {"h264": (True, True), "hevc": (True, True), "prores": (True, False)}

#: frames not restored listed in the sidecar (the count is always there)
_UNRESTORED_LISTED = 100

#: the keywords of restore_video that are not the method's
_FILE_KEYS = ("format", "bits", "quality", "mask", "water_mask", "max_memory", "max_pixels")


def _codec(choice: str, info: video.StreamInfo) -> str:
    if choice != "input":
        return choice
    got = _INPUT_CODECS.get(info.codec)
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
        with video._open(path) as c:
            return _codec(choice, video._info(path, c, "bt709"))
    except (ValueError, OSError):
        return choice


def _ffmpeg_text(e: BaseException) -> str:
    """FFmpeg's reason without the file name it names (a temporary's, which means nothing to the user)."""
    why = getattr(e, "strerror", None) or str(e) or type(e).__name__
    log = getattr(e, "log", None)
    if isinstance(log, tuple) and len(log) == 3 and log[2]:
        why += f" ({str(log[2]).strip()})"
    return why


def _check_size(codec: str, size: tuple[int, int], label: str, max_side) -> None:
    """ParameterError when ``codec`` cannot hold frames of ``size`` (H, W):
    4:2:0 needs an even width and height, 4:2:2 an even width."""
    need_w, need_h = _EVEN.get(codec, (False, False))
    h, w = size
    if (need_w and w % 2) or (need_h and h % 2):
        sub, sides = ("4:2:2", "an even width") if not need_h else ("4:2:0", "an even width and height")
        raise ParameterError(f"{label}: the restored frames are {w}x{h} pixels; {codec} is written {sub}, which "
                             f"needs {sides}: give --video-codec ffv1 or mjpeg (any size)"
                             + (", or another --max-side" if max_side else ""))


def _extension(in_path: str, codec: str) -> str:
    """The restored video's extension: the input's when its container takes the codec, else the codec's first."""
    ext = os.path.splitext(in_path)[1].lower()
    allowed = CODECS[codec][3]
    return ext if ext in allowed else allowed[0]


def video_suffixes(in_path: str, *, every: int | None, codec: str = "h264") -> list[str]:
    """What follows ``NAME`` in the names of a video's outputs, in writing
    order, without the sidecar's ``.json``: the restored video (not with
    ``every``) and the strip. ``codec`` "input" is taken as h264 here (the
    extension is checked against the stream when it is opened)."""
    if every:
        return ["_strip.jpg"]
    c = "h264" if codec == "input" else codec
    return [_extension(in_path, c), "_strip.jpg"]


def still_name(name: str, t: float | None, index: int) -> str:
    """The output name of the still at ``t`` seconds (``NAME_00h01m02s345``),
    or of frame ``index`` when the stream has no timestamps (``NAME_f000123``)."""
    if t is None or not math.isfinite(t) or t < 0:
        return f"{name}_f{index:06d}"
    ms = int(round(t * 1000))
    h, rest = divmod(ms, 3_600_000)
    m, rest = divmod(rest, 60_000)
    s, ms = divmod(rest, 1000)
    return f"{name}_{h:02d}h{m:02d}m{s:02d}s{ms:03d}"


@dataclass
class VideoResult:
    """What :func:`restore_video` did."""

    #: role ("video" or "stills", "strip", "sidecar") -> path (stills: a list)
    paths: dict = field(default_factory=dict)
    sidecar: dict = field(default_factory=dict)
    #: None, or where decoding stopped (``{"frame", "time", "error"}``)
    stopped: dict | None = None


def _plan(info: video.StreamInfo, s: int, out_bpp: float) -> int:
    """Bytes one frame needs at its peak: FFmpeg's frame and its 16-bit RGB
    copy, the linear frame, the restoration (the binary's plan) and the
    encoder's queue (x264's default look-ahead: about 48 frames)."""
    h, w = info.height, info.width
    plan = _core.input_plan(h, w, 6, True, False, s, False, 0, 20)
    hp, wp = -(-h // s), -(-w // s)
    return int(plan + 3 * h * w + 48 * out_bpp * hp * wp + (32 << 20))


class _Strip:
    """Thumbnails of frames spread over the video: input above, restored below."""

    def __init__(self, expected: int | None, rotation: int = 0):
        self.every = max(1, (expected or 240) // _STRIP_FRAMES)
        self.cells: list[tuple[np.ndarray, np.ndarray, str]] = []
        #: quarter turns counter-clockwise (np.rot90) that show the frames as a player does
        self.turns = (rotation // 90) % 4

    def offer(self, k: int, frame_in: np.ndarray, rf) -> None:
        if k % self.every or len(self.cells) >= 4 * _STRIP_FRAMES or rf.restoration is None:
            return
        s = max(1, -(-max(frame_in.shape[:2]) // _STRIP_CELL))

        def small(a):
            a = _core._downscale(np.ascontiguousarray(a, dtype=np.float32), s) if s > 1 else a
            return np.ascontiguousarray(np.rot90(a, self.turns)) if self.turns else a

        t = f"frame {rf.index}" if rf.time is None else f"{rf.time:.1f} s"
        self.cells.append((small(frame_in), small(rf.image), f"{t}, {rf.restoration.water_type}"))

    def encode(self) -> bytes:
        from PIL import Image, ImageDraw

        cells = self.cells[:: max(1, -(-len(self.cells) // _STRIP_FRAMES))][:_STRIP_FRAMES] or []
        if not cells:
            return b""
        h, w = cells[0][0].shape[:2]
        bar, pad = 18, 4
        sheet = Image.new("RGB", (len(cells) * (w + pad) + pad, 2 * h + bar + 3 * pad), (24, 24, 24))
        draw = ImageDraw.Draw(sheet)
        for i, (a, b, label) in enumerate(cells):
            x = pad + i * (w + pad)
            for row, img in enumerate((a, b)):
                u8 = (np.clip(uwhl_rs.to_srgb(img), 0, 1) * 255 + 0.5).astype(np.uint8)
                sheet.paste(Image.fromarray(u8), (x, pad + row * (h + pad)))
            draw.text((x + 2, 2 * h + 2 * pad + 2), label, fill=(235, 235, 235))
        import io

        buf = io.BytesIO()
        sheet.save(buf, "JPEG", quality=90)
        return buf.getvalue()


class _Writer:
    """The restored video, encoded into a temporary as frames come."""

    def __init__(self, tmp: str, ext: str, codec: str, info: video.StreamInfo, size: tuple[int, int],
                 crf: int, src):
        import av

        encoder, pix8, pix_deep, _ = CODECS[codec]
        self.av = av
        self.pix = pix_deep if info.bits > 8 else pix8
        self.bits = 16
        self.transfer = info.transfer
        #: streams dropped part way (a packet the container refused), and frames whose timestamp was not increasing
        self.notes: list[str] = []
        self.retimed = 0
        fmt = {".mkv": "matroska", ".ts": "mpegts", ".mts": "mpegts", ".m2ts": "mpegts", ".m4v": "mp4"}.get(ext)
        try:
            self.out = av.open(tmp, "w", format=fmt or ext.lstrip("."))
        except (av.FFmpegError, ValueError) as e:
            raise CommandError(f"cannot write a {ext} video: {_ffmpeg_text(e)}", "write_failed") from None
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
            # the frames were encoded with, BT.709's matrix, limited range
            # (full for motion JPEG)
            from av.video.reformatter import ColorPrimaries, ColorRange, Colorspace, ColorTrc

            trc = {"bt709": ColorTrc.BT709, "srgb": ColorTrc.IEC61966_2_1, "gamma22": ColorTrc.GAMMA22,
                   "gamma28": ColorTrc.GAMMA28, "linear": ColorTrc.LINEAR}[info.transfer]
            prim = src.streams.video[0].codec_context.color_primaries
            cc.color_primaries = int(prim) if int(prim or 2) != 2 else int(ColorPrimaries.BT709)
            cc.color_trc = int(trc)
            self.rgb = self.pix.startswith("rgb")
            cc.colorspace = int(Colorspace.RGB if self.rgb and hasattr(Colorspace, "RGB") else Colorspace.ITU709)
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
                               f"file: {_ffmpeg_text(e)}", "unreadable_input") from None
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
                              f"the container refused a packet ({_ffmpeg_text(e)})")

    def write(self, image: np.ndarray, pts: int | None) -> None:
        codes = _core.frame_from_linear(np.ascontiguousarray(image, dtype=np.float32), self.transfer, 16)
        f = self.av.VideoFrame.from_ndarray(codes, format="rgb48le")
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
        except self.av.FFmpegError as e:
            raise CommandError(f"cannot write the restored video at frame {self.frames}: {_ffmpeg_text(e)}",
                               "write_failed") from None
        self.frames += 1

    def close(self, flush: bool = True) -> None:
        try:
            if flush:
                for p in self.video.encode():
                    self.out.mux(p)
        except self.av.FFmpegError as e:
            raise CommandError(f"cannot finish the restored video: {_ffmpeg_text(e)}", "write_failed") from None
        finally:
            self.out.close()


def _progress_text(label: str, k: int, total: int | None, t0: float) -> str:
    dt = max(time.perf_counter() - t0, 1e-9)
    fps = k / dt
    if total:
        left = max(total - k, 0) / max(fps, 1e-9)
        return f"{label}: frame {k} of {total} ({100 * k / total:.0f}%), {fps:.1f} frames/s, ETA {_clock(left)}"
    return f"{label}: frame {k}, {fps:.1f} frames/s"


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


def restore_video(in_path, out_dir, *, name: str | None = None, every: int | None = None,
                  video_codec: str = "h264", video_quality: int = 18, transfer: str | None = None,
                  max_side: int | None = None, reuse_estimates: int | None = None, reuse_water_mask: bool = False,
                  scene_cut: float | None = None, smoothing: float | None = None, overwrite: bool = True,
                  progress: Callable[[str], None] | None = None, _claim=None, _label: str | None = None,
                  _stop=None, **options) -> VideoResult:
    """Restore the video at ``in_path`` into ``out_dir`` (module docs).

    ``options``: the photo options of :func:`uwhl_rs.files.restore_file`
    that apply (``format``, ``bits``, ``quality`` of the stills;
    ``max_memory``) and the method's keywords. ``reuse_estimates`` is the
    schedule of estimates in restored frames (default: a second of video),
    ``scene_cut`` and ``smoothing`` those of :func:`uwhl_rs.video.restore_frames`.
    ``progress`` is called with a line of text now and then. ``_claim``
    (the command's): the claimed output names (:func:`video_suffixes`).
    ``_stop`` (the command's): a ``threading.Event`` that, once set (an
    interrupt), stops the video at its next frame: nothing of it is kept.
    A frame that holds nothing to restore (black, flat) is written as it
    came in and counted (the sidecar's ``video.unrestored``).
    """
    t_start = time.perf_counter()
    in_path, out_dir = os.fspath(in_path), os.fspath(out_dir)
    # the name as sidecars and lines hold it (undecodable bytes of a file name as U+FFFD)
    label = display(_label or in_path)
    fmt, bits, jpeg_quality = options.pop("format", "jpg"), options.pop("bits", None), options.pop("quality", 95)
    for k in ("mask", "water_mask", "distance", "altitude", "fov", "water_from", "contact", "half_size",
              "preprocess", "port"):
        v = options.pop(k, None)
        if v not in (None, False, "none", "flat"):
            raise ParameterError(f"{k} is for photos: a video is restored as a sequence of frames")
    max_pixels = options.pop("max_pixels", None)
    settings = _core.FileSettings(format=fmt, bits=bits, quality=jpeg_quality, max_side=max_side, **options)
    budget = settings.max_memory
    info = video.probe(in_path, transfer=transfer)
    codec = _codec(video_codec, info)
    if max_pixels is not None and info.width * info.height > int(max_pixels):
        raise ImageTooLargeError(f"{label}: {info.width}x{info.height} frames are over max_pixels {max_pixels}")
    s = 1 if not max_side else max(1, -(-max(info.height, info.width) // int(max_side)))
    if not every:
        _check_size(codec, (-(-info.height // s), -(-info.width // s)), label, max_side)
    need = _plan(info, s, 6.0 if info.bits > 8 else 3.0)
    if need > budget:
        raise ImageTooLargeError(f"{label}: frames of {info.width}x{info.height} need about {need} bytes, over "
                                 f"max_memory {budget} (use max_side or raise max_memory)")
    name = name or os.path.splitext(os.path.basename(in_path))[0]
    suffixes = video_suffixes(in_path, every=every, codec=codec)
    claim = _claim
    if claim is None:
        status, side, why, claim = _core.claim_outputs(out_dir, name, in_path, suffixes, True, False)
        if status != "claimed":
            raise OSError(f"{side} is {why}")
    try:
        return _run(in_path, claim, info, codec, settings, dict(
            every=every, video_quality=video_quality, transfer=transfer, max_side=max_side,
            reuse_estimates=reuse_estimates, reuse_water_mask=reuse_water_mask, scene_cut=scene_cut,
            smoothing=smoothing, overwrite=overwrite, progress=progress, label=label, t_start=t_start, fmt=fmt,
            method=options, still_dir=os.path.dirname(str(claim.paths[-1])), stop=_stop))
    finally:
        claim.release()


def _run(in_path, claim, info, codec, settings, o) -> VideoResult:
    every, label = o["every"], o["label"]
    paths = [str(p) for p in claim.paths]
    reader = video.read_frames(in_path, transfer=o["transfer"], every=every or 1, max_side=o["max_side"])
    temps: list[str] = []
    writer = None
    notes: list[str] = []
    try:
        if not every:
            tmp = str(claim.temp(0))
            temps.append(tmp)
            size = (-(-info.height // _factor(info, o["max_side"])), -(-info.width // _factor(info, o["max_side"])))
            writer = _Writer(tmp, os.path.splitext(paths[0])[1], codec, info, size, int(o["video_quality"]), reader._c)
            dropped = [x for x in info.others if x["index"] not in writer.audio and x["type"] != "video"]
            if dropped:
                notes.append("streams not copied (the container or codec does not take them): "
                             + ", ".join(f"#{x['index']} {x['type']} {x['codec']}" for x in dropped))
            videos = [x for x in info.others if x["type"] == "video"]
            if videos:
                notes.append("only the first video stream is restored; not copied: "
                             + ", ".join(f"#{x['index']} video {x['codec']}" for x in videos))
            reader.on_packet = writer.copy
        strip = _Strip((info.frames or 0) // (every or 1) or None, info.rotation)
        events, stills, counts = [], [], {"restored": 0, "reused": 0, "flags": {}}
        unrestored: list[dict] = []
        n_unrestored = 0
        refresh = o["reuse_estimates"] or video.refresh_for(info.rate, every or 1)
        last_note = time.perf_counter()
        restored = video.restore_frames(
            reader, refresh_every=refresh, reuse_water_mask=o["reuse_water_mask"],
            scene_cut=_core.VIDEO_SCENE_CUT if o["scene_cut"] is None else o["scene_cut"],
            smoothing=_core.VIDEO_SMOOTHING if o["smoothing"] is None else o["smoothing"], unrestored="input",
            **o["method"])
        t_loop = time.perf_counter()
        for rf in restored:
            if o["stop"] is not None and o["stop"].is_set():
                raise KeyboardInterrupt  # the claim's release removes the temporaries: nothing of the video stays
            if rf.restoration is None:
                # nothing to restore (a black or flat frame): written as it came in, so no frame goes missing
                n_unrestored += 1
                if len(unrestored) < _UNRESTORED_LISTED:
                    unrestored.append({"frame": rf.index, "time": rf.time, "error": rf.error})
                if writer is not None:
                    writer.write(rf.image, rf.pts)
                else:
                    stills.append({"frame": rf.index, "time": rf.time, "image": None, "sidecar": None,
                                   "skipped": f"not restored: {rf.error}"})
                continue
            res = rf.restoration
            counts["restored"] += 1
            for f in res.flags:
                counts["flags"][f] = counts["flags"].get(f, 0) + 1
            if rf.decision == "reused":
                counts["reused"] += 1
            else:
                events.append({"frame": rf.index, "time": rf.time, "event": rf.decision,
                               "change": round(rf.change, 4), "water_type": res.water_type,
                               "veiling_light": [round(float(v), 6) for v in res.veiling_light]})
            strip.offer(counts["restored"] - 1, reader.last_input, rf)
            if writer is not None:
                writer.write(rf.image, rf.pts)
            else:
                stills.append(_write_still(claim.name, rf, info, settings, o))
            if o["progress"] is not None and time.perf_counter() - last_note > 5:
                last_note = time.perf_counter()
                total = info.frames // (every or 1) if info.frames else None
                o["progress"](_progress_text(label, counts["restored"], total, t_loop))
        writer_notes = []
        if writer is not None:
            writer.close()
            writer_notes = list(writer.notes)
            if writer.retimed:
                writer_notes.append(f"{writer.retimed} frames' timestamps were missing or did not increase (repeated "
                                    "or out of order): each was written one frame after the frame before it")
            writer = None
        t_done = time.perf_counter()
        if counts["restored"] == 0:
            why = unrestored[0]["error"] + f" (every one of its {n_unrestored} frames)" if unrestored else \
                reader.stopped["error"] if reader.stopped else "the stream has no frame"
            raise CommandError(f"no frame could be restored: {why}", "unreadable_input")
        if writer_notes:
            notes.extend(writer_notes)
        strip_bytes = strip.encode()
        tmp = str(claim.temp(len(paths) - 2))
        with open(tmp, "wb") as f:
            f.write(strip_bytes)
        temps.append(tmp)
        counts["unrestored"], counts["unrestored_list"] = n_unrestored, unrestored
        side = _sidecar(in_path, label, paths, info, codec, settings, o, events, stills, counts, reader, notes,
                        t_loop - o["t_start"], t_done - t_loop)
        tmp = str(claim.temp(len(paths) - 1))
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(side, f, indent=2, ensure_ascii=False)
            f.write("\n")
        temps.append(tmp)
        claim.commit(temps)
    finally:
        if writer is not None:
            writer.close(flush=False)
        reader.close()
    out = {"strip": paths[-2], "sidecar": paths[-1]}
    out["stills" if every else "video"] = [s["image"] for s in stills] if every else paths[0]
    return VideoResult(out, side, reader.stopped)


def _factor(info: video.StreamInfo, max_side) -> int:
    return 1 if not max_side else max(1, -(-max(info.height, info.width) // int(max_side)))


def _write_still(video_name: str, rf, info: video.StreamInfo, settings, o) -> dict:
    """One still of ``--every``: its photo outputs and sidecar (the photo
    path's writing half), unless a sidecar of it exists (a rerun)."""
    name = still_name(video_name, rf.time, rf.index)
    res = rf.restoration
    label = f"{o['label']}#{rf.index}"
    d = o["still_dir"]
    # a name another input holds (a photo called as the still would be) is not this still's: the next is taken
    status, side, why, claim = files.claim_outputs(d, name, label, o["fmt"], False, overwrite=o["overwrite"],
                                                   rename=True)
    entry = {"frame": rf.index, "time": rf.time, "image": None, "sidecar": os.path.basename(str(side))}
    if status != "claimed":
        entry["skipped"] = "sidecar exists" if status == "done" else (why or status)
        return entry
    try:
        h, w = res.transmission.shape
        source = {"kind": "linear", "format": f"video frame ({info.codec})", "bits": 16 if info.bits > 8 else 8,
                  "height": info.height, "width": info.width, "orientation": 1, "linear": True,
                  "preprocess": "none", "processed_height": int(h), "processed_width": int(w),
                  "icc_profile": None, "camera_matrix": None, "white_balance": None,
                  "notes": [f"frame {rf.index} of {os.path.basename(o['label'])} at "
                            f"{'?' if rf.time is None else f'{rf.time:.3f}'} s; {rf.decision} estimate"],
                  "path": label}
        text = _core.write_input_outputs(claim, res, np.ascontiguousarray(res.image), source, settings, None, label,
                                         None, rf.decision == "reused", 0.0, 0.0, None, 0.0)
    finally:
        claim.release()
    written = json.loads(text)
    entry["image"] = written["outputs"]["image"]
    return entry


def _thinned(events: list[dict]) -> list[dict]:
    """At most ``sidecars.VIDEO_ESTIMATES`` of the estimates, in frame order:
    the first, the cuts and the drifts, then the scheduled ones evenly."""
    from .sidecars import VIDEO_ESTIMATES

    if len(events) <= VIDEO_ESTIMATES:
        return events
    keep = [e for e in events if e["event"] != "scheduled"][:VIDEO_ESTIMATES]
    rest = [e for e in events if e["event"] == "scheduled"]
    room = VIDEO_ESTIMATES - len(keep)
    if room > 0:
        keep += rest[:: max(1, -(-len(rest) // room))][:room]
    return sorted(keep, key=lambda e: e["frame"])


def _dominant(events: list[dict], decoded: int) -> dict:
    """The estimate in use over the most frames (the video's water type and A in one line)."""
    best, most = events[0], -1
    for i, e in enumerate(events):
        end = events[i + 1]["frame"] if i + 1 < len(events) else max(decoded, e["frame"] + 1)
        if end - e["frame"] > most:
            best, most = e, end - e["frame"]
    return best


def _sidecar(in_path, label, paths, info, codec, settings, o, events, stills, counts, reader, notes,
             t_open: float, t_frames: float) -> dict:
    """The video's sidecar (docs/OUTPUTS.md "Videos")."""
    every = o["every"]
    main = _dominant(events, reader.decoded)
    flags = sorted(f for f, n in counts["flags"].items() if n >= 0.3 * counts["restored"] and f != "estimates_reused")
    if reader.stopped is not None:
        flags.append("video_truncated")
    base = os.path.basename
    output = None
    if not every:
        encoder, pix8, pix_deep, _ = CODECS[codec]
        output = {"codec": codec, "encoder": encoder, "pix_fmt": pix_deep if info.bits > 8 else pix8,
                  "crf": int(o["video_quality"]) if codec in ("h264", "hevc") else None, "transfer": info.transfer,
                  "matrix": "rgb" if codec == "ffv1" else "bt709"}
    return {
        "input": label,
        "kind": "video",
        "implementation": "python",
        "uwhl_version": uwhl_rs.__version__,
        "outputs": {"video": None if every else base(paths[0]), "strip": base(paths[-2])},
        "water_type": main["water_type"],
        "veiling_light": main["veiling_light"],
        "flags": flags,
        "video": {
            "stream": info.to_dict(),
            "output": output,
            "frames": {"decoded": int(reader.decoded), "restored": counts["restored"], "reused": counts["reused"],
                       "unrestored": counts["unrestored"], "every": int(every or 1)},
            "unrestored": counts["unrestored_list"],
            "stopped": reader.stopped,
            "schedule": {"refresh_every": int(o["reuse_estimates"] or video.refresh_for(info.rate, every or 1)),
                         "scene_cut": _core.VIDEO_SCENE_CUT if o["scene_cut"] is None else float(o["scene_cut"]),
                         "smoothing": _core.VIDEO_SMOOTHING if o["smoothing"] is None else float(o["smoothing"])},
            "estimates": _thinned(events),
            "estimates_total": len(events),
            "flag_frames": counts["flags"],
            "stills": stills,
            "notes": notes,
        },
        "parameters": json.loads(settings.parameters),
        "seconds": {"open": round(t_open, 4), "frames": round(t_frames, 4), "total": round(t_open + t_frames, 4)},
    }
