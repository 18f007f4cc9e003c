"""Rendered videos with known truth, for the tests and benches of videos
(docs/API.md "Videos"): a camera panning along a rendered reef
(:func:`uwhl_rs.synth.scene`, METHOD §0) through one water, optionally
cut to another reef in other water, or descending slowly so that the
veiling light drifts. Nothing is downloaded.

>>> c = clip(frames=12, height=64, width=96, cut_at=6)
>>> len(c.frames), c.water_types[0], c.water_types[-1]
(12, '3C', '7C')
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from . import _core, synth

__all__ = ["Clip", "clip", "write_clip", "patch_track"]


@dataclass
class Clip:
    """A rendered clip and its truth."""

    #: linear float32 (H, W, 3) frames
    frames: list = field(default_factory=list)
    #: the true water type and veiling light of each frame
    water_types: list = field(default_factory=list)
    veiling_lights: list = field(default_factory=list)
    #: the first frame after the cut (None: no cut)
    cut_at: int | None = None
    #: columns the camera moves a frame
    pan: int = 0
    #: frames a second
    rate: int = 24
    #: the world column of the left edge of frame 0
    start: int = 0


def _reef(water_type: str, height: int, width: int, seed: int, a=None) -> tuple[np.ndarray, np.ndarray]:
    """A wide scene (clean radiance, distance) to pan along, and its veiling light."""
    sc = synth.scene(height, width, kind="open_water", seed=seed)
    return sc, np.asarray(a if a is not None else synth.default_veiling_light(water_type), dtype=np.float64)


def clip(frames: int = 48, height: int = 144, width: int = 192, *, water_type: str = "3C", cut_at: int | None = None,
         second_type: str = "7C", pan: int = 3, noise: float = 0.005, descent: float = 0.0, rate: int = 24,
         seed: int = 0) -> Clip:
    """A camera panning ``pan`` columns a frame along a reef in
    ``water_type`` (beta_B 0.2 / m), with Gaussian noise ``noise``; from
    frame ``cut_at`` on, another reef in ``second_type`` (a cut). With
    ``descent`` d > 0 the veiling light's green and red fade by the factor
    ``exp(-d k / frames)`` over the clip (a slow descent: the water's colour
    changes gradually, no cut)."""
    if frames < 1 or height < 8 or width < 8 or pan < 0:
        raise ValueError("frames >= 1, height and width >= 8 and pan >= 0 are needed")
    wide = width + pan * frames
    out = Clip(cut_at=cut_at, pan=pan, rate=rate)
    rng = np.random.default_rng(seed)
    scenes = {0: _reef(water_type, height, wide, seed)}
    if cut_at is not None:
        scenes[1] = _reef(second_type, height, wide, seed + 101)
    for k in range(frames):
        part = 1 if cut_at is not None and k >= cut_at else 0
        wt = second_type if part else water_type
        sc, a = scenes[part]
        if descent > 0:
            fade = np.exp(-descent * k / frames)
            a = a * np.array([fade, fade ** 0.5, 1.0])
        x0 = pan * k
        clean = sc.clean[:, x0:x0 + width]
        z = sc.distance[:, x0:x0 + width]
        img = synth.render(clean, z, wt, veiling_light=tuple(a), beta_b=0.2, noise=0.0)
        img = np.clip(img + rng.normal(0.0, noise, img.shape), 0, 1).astype(np.float32)
        out.frames.append(img)
        out.water_types.append(wt)
        out.veiling_lights.append(tuple(float(v) for v in a))
    return out


def patch_track(c: Clip, k: int, size: int = 12) -> tuple[slice, slice] | None:
    """Where a patch of the seabed fixed in the world (its left edge at
    column ``width - size - 4`` of frame 0, near the bottom) is in frame
    ``k``, or None once it has left the frame."""
    h, w = c.frames[0].shape[:2]
    x = w - size - 4 - c.pan * k
    if x < 0:
        return None
    return slice(h - 3 * size, h - 2 * size), slice(x, x + size)


def write_clip(path: str | os.PathLike, c: Clip, *, codec: str = "ffv1", bits: int = 16, crf: int = 0,
               audio: bool = False) -> None:
    """``c`` as a video file: its frames through the BT.709 curve, tagged
    BT.709, at ``c.rate`` frames a second; ``codec`` "ffv1" (16-bit RGB,
    lossless) or "h264" (``bits`` 8 or 10, ``crf``); ``audio`` adds a
    second of a 440 Hz tone as an AAC stream (to see it copied)."""
    import av
    from av.video.reformatter import ColorPrimaries, ColorRange, Colorspace, ColorTrc

    path = os.fspath(path)
    h, w = c.frames[0].shape[:2]
    with av.open(path, "w") as out:
        if codec == "ffv1":
            st = out.add_stream("ffv1", rate=c.rate)
            st.pix_fmt = "rgb48le"
        else:
            st = out.add_stream("libx264", rate=c.rate)
            st.pix_fmt = "yuv420p10le" if bits > 8 else "yuv420p"
            st.options = {"crf": str(crf)}
        st.width, st.height = w, h
        cc = st.codec_context
        cc.color_primaries = int(ColorPrimaries.BT709)
        cc.color_trc = int(ColorTrc.BT709)
        rng = ColorRange.JPEG if codec == "ffv1" else ColorRange.MPEG
        cc.colorspace = int(Colorspace.ITU709)
        cc.color_range = int(rng)
        a_st = None
        if audio:
            a_st = out.add_stream("aac", rate=48000)
            a_st.layout = "mono"
        for k, img in enumerate(c.frames):
            codes = _core.frame_from_linear(np.ascontiguousarray(img, dtype=np.float32), "bt709", 16)
            f = av.VideoFrame.from_ndarray(codes, format="rgb48le")
            if codec != "ffv1":
                f = f.reformat(format=st.pix_fmt, dst_colorspace="ITU709", dst_color_range=rng)
            f.pts = k
            for p in st.encode(f):
                out.mux(p)
        for p in st.encode():
            out.mux(p)
        if a_st is not None:
            n = int(48000 * len(c.frames) / c.rate)
            tone = (0.2 * np.sin(2 * np.pi * 440 * np.arange(n) / 48000)).astype(np.float32)[None, :]
            for i in range(0, n, 1024):
                fr = av.AudioFrame.from_ndarray(tone[:, i:i + 1024], format="flt", layout="mono")
                fr.sample_rate = 48000
                fr.pts = i
                for p in a_st.encode(fr):
                    out.mux(p)
            for p in a_st.encode():
                out.mux(p)
