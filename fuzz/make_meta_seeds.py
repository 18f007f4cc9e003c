"""Writes the seeds of the metadata fuzz targets (committed; rerun to
regenerate): fuzz/meta_seeds/<target>/ for meta_exif, meta_xmp, meta_icc,
meta_container and meta_carry. Each seed is built here byte by byte (EXIF
blocks, XMP packets, ICC profiles from Pillow's ImageCms, JPEG and PNG
files around them), the valid shapes beside the hostile ones of issue 30."""

import io
import os
import shutil
import struct
import zlib

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
    }
    for target, seeds in groups.items():
        os.makedirs(os.path.join(HERE, target))
        for name, data in seeds.items():
            with open(os.path.join(HERE, target, name), "wb") as f:
                f.write(data)
    print({t: len(s) for t, s in groups.items()})


if __name__ == "__main__":
    main()
