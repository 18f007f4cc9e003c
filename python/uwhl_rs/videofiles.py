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

import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

import uwhl_rs

from . import _core, files, video
from .videoencode import CODECS, Writer, check_size, codec_for, extension, resolve_codec, write_error
from .errors import CommandError, ImageTooLargeError, ParameterError
from .sidecars import display
from .storage import sha256_of

__all__ = ["VideoResult", "video_suffixes", "restore_video", "still_name", "resolve_codec", "frame_need", "CODECS"]

#: frames of the strip
_STRIP_FRAMES = 8
#: the longer side of a strip cell
_STRIP_CELL = 240

#: frames not restored listed in the sidecar (the count is always there)
_UNRESTORED_LISTED = 100

#: the keywords of restore_video that are not the method's
_FILE_KEYS = ("format", "bits", "quality", "mask", "water_mask", "max_memory", "max_pixels")


def video_suffixes(in_path: str, *, every: int | None, codec: str = "h264") -> list[str]:
    """What follows ``NAME`` in the names of a video's outputs, in writing
    order, without the sidecar's ``.json``: the restored video and the
    strip. With ``every`` the video's name is claimed too, and not written:
    the commit removes a video an earlier run left there (``--overwrite``).
    With ``codec`` "input" the video keeps the input's extension (checked
    against its codec once it is opened)."""
    if codec == "input":
        # the input's own container when any codec goes in it (checked against its codec once it is opened)
        ext = os.path.splitext(in_path)[1].lower()
        return [ext if any(ext in c[3] for c in CODECS.values()) else ".mp4", "_strip.jpg"]
    return [extension(in_path, codec), "_strip.jpg"]


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


def frame_need(info: video.StreamInfo, max_side: int | None = None) -> int:
    """Bytes restoring a video of this stream needs at its peak (a frame's plan)."""
    return _plan(info, files.max_side_factor(info.height, info.width, max_side), 6.0 if info.bits > 8 else 3.0)


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
        s = files.max_side_factor(*frame_in.shape[:2], _STRIP_CELL)

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


def _expected_frames(info: video.StreamInfo, every: int | None) -> int | None:
    """The frames to restore, for the progress line: the header's count when
    its duration and rate agree with it (a header may state 2^32 frames),
    else duration x rate; None when neither is known."""
    by_time = int(info.duration * float(info.rate)) + 1 if info.duration and info.rate else None
    n = info.frames_shown
    if n and by_time and n > 2 * by_time:
        n = by_time
    n = n or by_time
    return None if not n else max(1, n // (every or 1))


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
                  _stop=None, _flags: bool = False, _base: int | None = None, **options) -> VideoResult:
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
    ``_flags`` (the command's): errors name options by their flags
    (``--mask``, ``--max-memory``) instead of the keywords. ``_base``: what
    the process holds anyway, counted with the frames' plan against
    ``max_memory`` as a photo's ``_base`` is; None counts the process's
    base (``_core.process_base()``, as a batch's context does) when the
    command called (``_claim`` given), nothing for a direct call (as
    :func:`uwhl_rs.files.restore_file`).
    A frame that holds nothing to restore (black, flat) is written as it
    came in and counted (the sidecar's ``video.unrestored``).
    """
    t_start = time.perf_counter()
    in_path, out_dir = os.fspath(in_path), os.fspath(out_dir)
    # the name as sidecars and lines hold it (undecodable bytes of a file name as U+FFFD)
    label = display(_label or in_path)
    fmt, bits, jpeg_quality = options.pop("format", "jpg"), options.pop("bits", None), options.pop("quality", 95)
    for k in ("mask", "water_mask", "distance", "altitude", "fov", "water_from", "contact", "half_size",
              "preprocess", "port", "distance_kind"):
        v = options.pop(k, None)
        if v not in (None, False, "none", "flat", "range"):
            raise ParameterError(f"{files.spelt(k, _flags)} is for photos: a video is restored as a sequence of "
                                 "frames")
    max_pixels = options.pop("max_pixels", None)
    settings = _core.FileSettings(format=fmt, bits=bits, quality=jpeg_quality, max_side=max_side, **options)
    budget = settings.max_memory
    # the headers only: the rotation decodes a frame, which waits for the memory check
    info = video.probe(in_path, transfer=transfer, rotation=False)
    codec = codec_for(video_codec, info)
    side, memory = files.spelt("max_side", _flags), files.spelt("max_memory", _flags)
    if max_pixels is not None and info.width * info.height > int(max_pixels):
        raise ImageTooLargeError(f"{label}: {info.width}x{info.height} frames are over "
                                 f"{files.spelt('max_pixels', _flags)} {max_pixels}")
    if not every:
        check_size(codec, _processed(info, max_side), label, max_side)
    if _base is None:
        # the batch context's base (uwhl_rs.tasks.context): the process before its first input and the
        # writer threads' 4 MiB, which a photo of the same run counts too
        _base = _core.process_base() + (4 << 20) if _claim is not None else 0
    frame = frame_need(info, max_side)
    need = frame + int(_base)
    if need > budget:
        raise ImageTooLargeError(f"{label}: frames of {info.width}x{info.height} need about {need} bytes, over "
                                 f"{memory} {budget} (use {side} or raise {memory})")
    if not _core.can_allocate(frame):
        # within the budget, but more than the system gives now (as a photo's plan is checked)
        raise ImageTooLargeError(f"{label}: frames of {info.width}x{info.height} need about {need} bytes, more "
                                 f"than the system gives now (free memory, a container limit or ulimit -v); use {side}")
    info.rotation = video.display_rotation(in_path)
    if name and _claim is None:
        files.check_name(name)  # a caller's name, never a path out of out_dir (a batch's are the core's, claimed)
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
    # stills are photos: upright in their pixels, as the strip is (a restored video keeps the display matrix)
    reader = video.read_frames(in_path, transfer=o["transfer"], every=every or 1, max_side=o["max_side"],
                               rotation=info.rotation if every else 0)
    temps: list[str] = []
    writer = None
    notes: list[str] = []
    try:
        if every:
            # the stills stand for the video: a restored video of an earlier run goes
            claim.omit(0)
        else:
            ext = os.path.splitext(paths[0])[1].lower()
            if ext not in CODECS[codec][3]:
                raise ParameterError(f"--video-codec {codec} cannot be written into a {ext} file (it goes into "
                                     f"{', '.join(CODECS[codec][3])}); give --video-codec h264")
            tmp = str(claim.temp(0))
            temps.append(tmp)
            writer = Writer(tmp, os.path.splitext(paths[0])[1], codec, info, _processed(info, o["max_side"]),
                            int(o["video_quality"]), reader._c, shown=display(paths[0]))
            dropped = [x for x in info.others if x["index"] not in writer.audio and x["type"] != "video"]
            if dropped:
                notes.append("streams not copied (the container or codec does not take them): "
                             + ", ".join(f"#{x['index']} {x['type']} {x['codec']}" for x in dropped))
            videos = [x for x in info.others if x["type"] == "video"]
            if videos:
                notes.append("only the first video stream is restored; not copied: "
                             + ", ".join(f"#{x['index']} video {x['codec']}" for x in videos))
            reader.on_packet = writer.copy
        strip = _Strip((info.frames_shown or 0) // (every or 1) or None, 0 if every else info.rotation)
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
                o["progress"](_progress_text(label, counts["restored"], _expected_frames(info, every), t_loop))
        writer_notes = []
        if writer is not None:
            writer.close()
            writer_notes = list(writer.notes)
            if writer.retimed:
                writer_notes.append(f"{writer.retimed} frames' timestamps were missing or did not increase (repeated "
                                    "or out of order): each was written one frame after the frame before it")
            if writer.rescaled:
                k, h, w = writer.first_rescaled
                writer_notes.append(f"{writer.rescaled} frames are not the video's {writer.size[1]}x{writer.size[0]} "
                                    f"(the stream changes size; the first, written frame {k}, is {w}x{h}): "
                                    f"each was written scaled to {writer.size[1]}x{writer.size[0]}")
            writer = None
        t_done = time.perf_counter()
        if reader.angle is not None and video.quarter_turns(reader.angle) is None:
            # turning the pixels shows quarter turns only: another angle is said, not dropped silently
            what = "the stills and the strip are not turned" if every else \
                "the restored video and the strip are not turned, and the video has no display matrix"
            notes.insert(0, f"the display matrix turns the frames {reader.angle:g} degrees, not a multiple of 90: "
                            f"not applied ({what})")
        if counts["restored"] == 0:
            why = unrestored[0]["error"] + f" (every one of its {n_unrestored} frames)" if unrestored else \
                reader.stopped["error"] if reader.stopped else "the stream has no frame"
            raise CommandError(f"no frame could be restored: {why}", "unreadable_input")
        if writer_notes:
            notes.extend(writer_notes)
        strip_bytes = strip.encode()
        tmp = str(claim.temp(len(paths) - 2))
        temps.append(tmp)
        try:
            with open(tmp, "wb") as f:
                f.write(strip_bytes)
        except OSError as e:
            raise write_error(display(paths[-2]), e) from None
        counts["unrestored"], counts["unrestored_list"] = n_unrestored, unrestored
        side = _sidecar(in_path, label, paths, info, codec, settings, o, events, stills, counts, reader, notes,
                        t_loop - o["t_start"], t_done - t_loop)
        tmp = str(claim.temp(len(paths) - 1))
        temps.append(tmp)
        try:
            with open(tmp, "w", encoding="utf-8") as f:
                json.dump(side, f, indent=2, ensure_ascii=False)
                f.write("\n")
        except OSError as e:
            raise write_error(display(paths[-1]), e) from None
        try:
            claim.commit(temps)
        except OSError as e:
            raise write_error(display(paths[-1] if every else paths[0]), e) from None
    finally:
        if writer is not None:
            writer.close(flush=False)
        reader.close()
    out = {"strip": paths[-2], "sidecar": paths[-1]}
    out["stills" if every else "video"] = [s["image"] for s in stills] if every else paths[0]
    return VideoResult(out, side, reader.stopped)


def _processed(info: video.StreamInfo, max_side) -> tuple[int, int]:
    """The restored frames' (height, width) after ``max_side``."""
    s = files.max_side_factor(info.height, info.width, max_side)
    return -(-info.height // s), -(-info.width // s)


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
        # the frame as a player shows it: its sides swapped by a quarter turn, which is recorded as the
        # EXIF orientation a photo turned the same way has (8: a quarter counter-clockwise)
        tall = info.rotation in (90, 270)
        source = {"kind": "linear", "format": f"video frame ({info.codec})", "bits": 16 if info.bits > 8 else 8,
                  "height": info.width if tall else info.height, "width": info.height if tall else info.width,
                  "orientation": {90: 8, 180: 3, 270: 6}.get(info.rotation, 1), "linear": True,
                  "preprocess": "none", "processed_height": int(h), "processed_width": int(w),
                  "icc_profile": None, "camera_matrix": None, "white_balance": None,
                  "notes": [f"frame {rf.index} of {os.path.basename(o['label'])} at "
                            f"{'?' if rf.time is None else f'{rf.time:.3f}'} s; {rf.decision} estimate"],
                  "path": label}
        text = _core.write_input_outputs(claim, res, np.ascontiguousarray(res.image), source, settings, None, label,
                                         None, rf.decision == "reused", 0.0, 0.0, None, 0.0)
    except OSError as e:
        # a full disk is the output's failure (exit 5), not the video's: it is read fine
        raise write_error(display(os.path.join(d, name)), e) from None
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


#: the video options of the option table, which a video's sidecar records when given
VIDEO_OPTIONS = ("every", "video_codec", "video_quality", "transfer", "scene_cut", "smoothing")
_VIDEO_DEFAULTS = {o["key"]: o["default"] for o in _core.OPTIONS if o["key"] in VIDEO_OPTIONS}


def given_video_options(options: dict) -> dict:
    """The video options of ``options`` that are not their defaults: what a
    video's sidecar records beside the photo's ``parameters``, so that a
    rerun with another ``--every`` or ``--video-codec`` says so (a video
    restored before they were recorded, with their defaults, matches)."""
    return {k: options[k] for k in VIDEO_OPTIONS
            if options.get(k) is not None and options[k] != _VIDEO_DEFAULTS.get(k)}


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
    doc = {
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
        "parameters": {**json.loads(settings.parameters), **given_video_options(o)},
        "seconds": {"open": round(t_open, 4), "frames": round(t_frames, 4), "total": round(t_open + t_frames, 4)},
    }
    # a local file's absolute path, links resolved, as a photo's sidecar
    # records it: a rerun from another folder recognises it, and the same
    # relative name in another dive is another input (docs/OUTPUTS.md); a
    # name that is not UTF-8 cannot be recorded (U+FFFD stands in for its
    # bytes), so the file's hash is
    resolved = os.path.realpath(in_path) if "://" not in str(label) else None
    if resolved is not None and resolved.encode("utf-8", "surrogateescape").decode("utf-8", "replace") == resolved:
        doc["input_resolved"] = resolved
    elif resolved is not None:
        # as a photo's sidecar records it (a rerun would otherwise restore it
        # again under NAME_2, NAME_3, ...)
        try:
            with open(in_path, "rb") as f:
                doc.setdefault("metadata", {})["input_sha256"] = sha256_of(f)
        except OSError:
            pass
    return doc
