"""Writes the seeds of the metadata fuzz targets (committed; rerun to
regenerate): fuzz/meta_seeds/<target>/ for meta_exif, meta_xmp, meta_icc,
meta_container, meta_carry and meta_depth. Each seed is built here byte by
byte (EXIF blocks, XMP packets, ICC profiles from Pillow's ImageCms, JPEG
and PNG files around them, distance maps in each format the readers take),
the valid shapes beside the hostile ones of issue 30 and of the reviews."""

import io
import os
import shutil
import struct
import zlib

import numpy as np
from PIL import Image, ImageCms

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "meta_seeds")


def ifd_block(entries, little=True, next_ifd=0, tail=b""):
    """A TIFF-structured block with one IFD0 at 8: entries (tag, type,
    count, 4 value bytes), its next-IFD link, then `tail` (at 8 + 2 + 12n + 4)."""
    e = "<" if little else ">"
    b = (b"II*\0" if little else b"MM\0*") + struct.pack(e + "I", 8) + struct.pack(e + "H", len(entries))
    for tag, kind, count, value in entries:
        b += struct.pack(e + "HHI", tag, kind, count) + value
    return b + struct.pack(e + "I", next_ifd) + tail


def short(v, little=True):
    return struct.pack("<HH" if little else ">HH", v, 0)


def long(v, little=True):
    return struct.pack("<I" if little else ">I", v)


def exif_blocks():
    n = 8 + 2 + 12 * 3 + 4
    camera = ifd_block([(0x010F, 2, 6, long(n)), (0x0112, 3, 1, short(6)), (0x8769, 4, 1, long(n + 6))],
                       tail=b"Canon\0" + struct.pack("<H", 1) + struct.pack("<HHI", 0x9003, 2, 20)
                       + long(n + 6 + 18) + long(0) + b"2026:01:02 03:04:05\0")
    return {
        "orientation_short": ifd_block([(0x0112, 3, 1, short(6))]),
        "orientation_long_be": ifd_block([(0x0112, 4, 1, long(8, False))], little=False),
        "orientation_count2": ifd_block([(0x0112, 3, 2, struct.pack("<HH", 3, 5))]),
        "camera_exif_subifd": camera,
        "loop_next": ifd_block([(0x0112, 3, 1, short(1))], next_ifd=8),
        "loop_subifd": ifd_block([(0x8769, 4, 1, long(8))]),
        "huge_count": ifd_block([(0x010F, 2, 0xFFFFFFFF, long(100))]),
        # a DateTimeOriginal holding non-ASCII UTF-8 (meta_carry once panicked on it)
        "time_not_ascii": ifd_block([(0x8769, 4, 1, long(8 + 2 + 12 + 4))], tail=struct.pack("<H", 1)
                                    + struct.pack("<HHI", 0x9003, 2, 21) + long(8 + 2 + 12 + 4 + 2 + 12 + 4) + long(0)
                                    + "2026:01:02 03:ÿÿÿ".encode() + b"\0"),
        "strips_too_big": ifd_block([(0x0111, 4, 1, long(0)), (0x0117, 4, 1, long(4000000000))]),
    }


def xmp_packets():
    wrap = ('<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?><x:xmpmeta xmlns:x="adobe:ns:meta/">'
            '<rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">{}</rdf:RDF></x:xmpmeta>'
            '<?xpacket end="w"?>')
    return {
        "attribute": wrap.format('<rdf:Description xmlns:tiff="http://ns.adobe.com/tiff/1.0/" tiff:Orientation="6"/>'),
        "element": wrap.format("<rdf:Description><tiff:Orientation>8</tiff:Orientation></rdf:Description>"),
        "unclosed": wrap.format('<rdf:Description tiff:Orientation="6/>'),
        "record": wrap.format('<rdf:Description rdf:about="" xmlns:uwhl="https://uwhl-rs.github.io/ns/restoration/1.0/">'
                              "<uwhl:WaterType>3C</uwhl:WaterType></rdf:Description>"),
    }


def icc_profiles():
    def fixed(name):
        # the header's creation date and profile ID zeroed: the same seeds at every run
        p = bytearray(ImageCms.ImageCmsProfile(ImageCms.createProfile(name)).tobytes())
        p[24:36] = bytes(12)
        p[84:100] = bytes(16)
        return bytes(p)

    srgb, lab = fixed("sRGB"), fixed("LAB")
    return {"srgb": srgb, "lab": lab, "truncated": srgb[:200]}


def chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png_file(*chunks):
    raw = b"".join(b"\0" + bytes([x * 40 % 256, 90, 200 - x * 30]) * 4 for x in range(3))
    ihdr = chunk(b"IHDR", struct.pack(">IIBBBBB", 4, 3, 8, 2, 0, 0, 0))
    return b"\x89PNG\r\n\x1a\n" + ihdr + b"".join(chunks) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def jpeg_file(*segments):
    buf = io.BytesIO()
    Image.new("RGB", (8, 8), (30, 90, 160)).save(buf, format="JPEG", quality=80)
    j = buf.getvalue()
    return j[:2] + b"".join(b"\xff" + bytes([m]) + struct.pack(">H", len(d) + 2) + d for m, d in segments) + j[2:]


def files(exif, xmp, icc):
    xmp_itxt = b"XML:com.adobe.xmp\0\0\0\0\0" + xmp["attribute"].encode()
    raw_exif = exif["orientation_short"].hex().encode()
    return {
        "jpeg_exif6.jpg": jpeg_file((0xE1, b"Exif\0\0" + exif["camera_exif_subifd"])),
        "jpeg_two_exif.jpg": jpeg_file((0xE1, b"Exif\0\0" + exif["orientation_short"]),
                                       (0xE1, b"Exif\0\0" + exif["orientation_long_be"])),
        "jpeg_time_not_ascii.jpg": jpeg_file((0xE1, b"Exif\0\0" + exif["time_not_ascii"])),
        "jpeg_loop.jpg": jpeg_file((0xE1, b"Exif\0\0" + exif["loop_next"])),
        "jpeg_xmp_icc.jpg": jpeg_file((0xE1, b"http://ns.adobe.com/xap/1.0/\0" + xmp["element"].encode()),
                                      (0xE2, b"ICC_PROFILE\0\1\1" + icc["srgb"])),
        "png_exif_loop.png": png_file(chunk(b"eXIf", exif["loop_subifd"])),
        "png_exif_xmp_icc.png": png_file(chunk(b"eXIf", exif["camera_exif_subifd"]), chunk(b"iTXt", xmp_itxt),
                                         chunk(b"iCCP", b"sRGB\0\0" + zlib.compress(icc["srgb"]))),
        "png_raw_profile.png": png_file(chunk(b"zTXt", b"Raw profile type exif\0\0" + zlib.compress(
            b"\nexif\n      %d\n" % (len(raw_exif) // 2) + raw_exif + b"\n"))),
        "png_lab_icc.png": png_file(chunk(b"iCCP", b"Lab\0\0" + zlib.compress(icc["lab"]))),
        "png_icc_bomb.png": png_file(chunk(b"iCCP", b"bomb\0\0" + zlib.compress(bytes(4 << 20), 9))),
        "tiff_orientation.tif": exif["orientation_long_be"],
    }


def tiff_float(w, h, values, big=False, little=True):
    """A one-strip float32 TIFF (or BigTIFF) of `w` x `h` values."""
    e = "<" if little else ">"
    data = struct.pack(e + "%df" % (w * h), *values)
    tags = [(0x0100, 3, w), (0x0101, 3, h), (0x0102, 3, 32), (0x0103, 3, 1), (0x0106, 3, 1),
            (0x0111, 4, 0), (0x0115, 3, 1), (0x0116, 3, h), (0x0117, 4, len(data)), (0x0153, 3, 3)]
    # BigTIFF: counts, links and value fields of 8 bytes; classic TIFF: of 4 (an entry count of 2)
    word, inline, count = ("Q", 8, "Q") if big else ("I", 4, "H")
    ifd_at = 16 if big else 8
    size = struct.calcsize(count) + len(tags) * (4 + 2 * inline) + inline
    head = (b"II" if little else b"MM") + (struct.pack(e + "HHHQ", 43, 8, 0, ifd_at) if big
                                           else struct.pack(e + "HI", 42, ifd_at))
    body = struct.pack(e + count, len(tags))
    for tag, kind, v in tags:
        v = ifd_at + size if tag == 0x0111 else v
        val = struct.pack(e + ("H" if kind == 3 else "I"), v).ljust(inline, b"\0")
        body += struct.pack(e + "HH" + word, tag, kind, 1) + val
    return head + body + struct.pack(e + word, 0) + data


def exr_float(w, h, values, channel=b"Z"):
    """A scanline OpenEXR file, uncompressed, of one FLOAT channel."""
    def attr(name, kind, value):
        return name + b"\0" + kind + b"\0" + struct.pack("<i", len(value)) + value
    chlist = channel + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + attr(b"channels", b"chlist", chlist)
              + attr(b"compression", b"compression", b"\0") + attr(b"dataWindow", b"box2i", box)
              + attr(b"displayWindow", b"box2i", box) + attr(b"lineOrder", b"lineOrder", b"\0")
              + attr(b"pixelAspectRatio", b"float", struct.pack("<f", 1.0))
              + attr(b"screenWindowCenter", b"v2f", struct.pack("<ff", 0, 0))
              + attr(b"screenWindowWidth", b"float", struct.pack("<f", 1.0)) + b"\0")
    start = len(header) + 8 * h
    rows, table = b"", b""
    for y in range(h):
        line = struct.pack("<%df" % w, *values[y * w:(y + 1) * w])
        table += struct.pack("<Q", start + len(rows))
        rows += struct.pack("<ii", y, len(line)) + line
    return header + table + rows


def depth_maps():
    w, h = 6, 5
    vals = [0.5 + 0.25 * i for i in range(w * h)]
    npy = io.BytesIO()
    np.save(npy, np.array(vals, np.float32).reshape(h, w))
    png = io.BytesIO()
    Image.fromarray(np.array([v * 1000 for v in vals], np.uint16).reshape(h, w)).save(png, format="PNG")
    # the tiff crate's dbg! case in BigTIFF: an ASCII ImageWidth of 2^48 bytes
    dbg = b"II" + struct.pack("<HHHQQ", 43, 8, 0, 16, 1) + struct.pack("<HHQQ", 0x0100, 2, 0xFFFFFFFFFF00, 0) \
        + struct.pack("<Q", 0)
    colmap = b"%d&%d&1&" % (w, h) + struct.pack("<%df" % (w * h), *vals)
    return {"map.npy": npy.getvalue(), "map16.png": png.getvalue(), "map.tif": tiff_float(w, h, vals),
            "map_be.tif": tiff_float(w, h, vals, little=False), "map_big.tif": tiff_float(w, h, vals, big=True),
            "ascii_width_big.tif": dbg, "map.exr": exr_float(w, h, vals), "map.geometric.bin": colmap}


def main():
    shutil.rmtree(HERE, ignore_errors=True)
    exif, xmp, icc = exif_blocks(), xmp_packets(), icc_profiles()
    containers = files(exif, xmp, icc)
    groups = {
        "exif": exif,
        "xmp": {k: v.encode() for k, v in xmp.items()},
        "icc": icc,
        "container": containers,
        "carry": containers,
        "depth": depth_maps(),
    }
    for target, seeds in groups.items():
        os.makedirs(os.path.join(HERE, target))
        for name, data in seeds.items():
            with open(os.path.join(HERE, target, name), "wb") as f:
                f.write(data)
    print({t: len(s) for t, s in groups.items()})


if __name__ == "__main__":
    main()
