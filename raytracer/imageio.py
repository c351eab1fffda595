"""Image files: OpenEXR (linear float32 RGB) and PNG (sRGB-encoded, 8- or 16-bit), written atomically.

A render is written to a temporary file in the destination folder and renamed over the target,
so an interrupted write never leaves a half-written image behind.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) of linear values, clipped to [0, 1]."""
    x = np.clip(np.nan_to_num(linear, nan=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    x = np.clip(encoded, 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))


def _atomic_write(path: Path, write) -> None:
    """``write(tmp)`` to a temporary file beside ``path``, then renamed over it: a reader never
    sees half an image. A symbolic link is followed (its target is replaced, the link stays) and a
    replaced file keeps its permissions; a new one gets 0666 less the umask."""
    path = Path(os.path.realpath(path)) if os.path.islink(path) else Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent or ".")
    os.close(fd)
    try:
        # mkstemp makes the file 0600
        try:
            mode = os.stat(path).st_mode & 0o7777
        except OSError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


class ImageClampWarning(UserWarning):
    """Pixels beyond the largest float32 (or infinite) were written as the largest float32."""


def _as_rgb(image, warn: bool = False) -> np.ndarray:
    """The image as float32 (H, W, 3). NaN is refused (nothing is written); a value beyond float32's
    range (an overflowed float64 render, or infinite) is clamped to it, with ``warn`` (the linear
    EXR, which keeps it) an :class:`ImageClampWarning` that counts the pixels (8-bit and 16-bit
    formats clip at 1 in any case)."""
    raw = np.asarray(image)
    if raw.ndim != 3 or raw.shape[-1] != 3:
        raise ValueError(f"expected an (H, W, 3) image, got shape {raw.shape}")
    if not np.issubdtype(raw.dtype, np.floating):
        raw = raw.astype(np.float64)
    if np.isnan(raw).any():
        raise ValueError(f"the image has {int(np.isnan(raw).any(-1).sum())} NaN pixels: not written")
    big = np.finfo(np.float32).max
    over = np.abs(raw) > big
    if over.any() and warn:
        import warnings

        warnings.warn(ImageClampWarning(
            f"{int(over.any(-1).sum())} pixels beyond the largest float32 (or infinite) written as "
            f"±{big:.4g}"), stacklevel=3)
    return np.clip(raw, -big, big).astype(np.float32)


def write_exr(path, image) -> None:
    """Writes linear float32 RGB OpenEXR."""
    import OpenEXR

    img = _as_rgb(image, warn=True)

    def write(tmp):
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        channels = {c: np.ascontiguousarray(img[..., i]) for i, c in enumerate("RGB")}
        try:
            with OpenEXR.File(header, channels) as f:
                f.write(tmp)
        except RuntimeError as e:  # OpenEXR's I/O failures (a full disk, a vanished folder)
            raise OSError(f"OpenEXR could not write it: {e}") from None

    _atomic_write(Path(path), write)


def write_png(path, image, *, bits: int = 8) -> None:
    """Writes sRGB-encoded PNG (8-bit, or 16-bit with ``bits=16``) from a linear image."""

    if bits == 8:
        _write_pillow(path, image, "PNG")
    elif bits == 16:
        enc = srgb_encode(_as_rgb(image))
        _atomic_write(Path(path), lambda tmp: _write_png16(tmp, np.round(enc * 65535).astype(np.uint16)))
    else:
        raise ValueError("bits must be 8 or 16")


def _write_png16(path, data: np.ndarray) -> None:
    # Pillow cannot write 48-bit RGB; write the PNG chunks ourselves (zlib + CRC, PNG spec §11).
    import struct
    import zlib

    h, w, _ = data.shape
    raw = b"".join(b"\x00" + data[y].astype(">u2").tobytes() for y in range(h))

    def chunk(tag, body):
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 2, 0, 0, 0))
           + chunk(b"sRGB", b"\x00") + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))
    with open(path, "wb") as f:
        f.write(png)


def _write_pillow(path, image, fmt: str, **options) -> None:
    """An 8-bit sRGB file in Pillow's format ``fmt``, written atomically."""
    from PIL import Image

    pil = Image.fromarray(np.round(srgb_encode(_as_rgb(image)) * 255).astype(np.uint8), "RGB")
    _atomic_write(Path(path), lambda tmp: pil.save(tmp, format=fmt, **options))


# 8-bit sRGB formats Pillow writes (POV-Ray's output types T and C, P, J, B)
_PILLOW_FORMATS = {".tga": "TGA", ".ppm": "PPM", ".jpg": "JPEG", ".jpeg": "JPEG", ".bmp": "BMP"}
WRITTEN_SUFFIXES = (".exr", ".png", *_PILLOW_FORMATS)


def write_image(path, image, *, bits: int = 8, rle: bool = False) -> None:
    """Writes ``image`` (H, W, 3, linear) as .exr (linear float32), .png (sRGB, 8 or 16 bits), or
    8-bit sRGB .tga (run-length encoded with ``rle``: POV-Ray's type C), .ppm, .jpg (quality 95)
    or .bmp."""
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        write_exr(path, image)
    elif suffix == ".png":
        write_png(path, image, bits=bits)
    elif suffix in _PILLOW_FORMATS:
        fmt = _PILLOW_FORMATS[suffix]
        _write_pillow(path, image, fmt, **({"compression": "tga_rle"} if fmt == "TGA" and rle
                                           else {"quality": 95} if fmt == "JPEG" else {}))
    else:
        raise ValueError(f"unsupported image format {suffix!r}: use one of {', '.join(WRITTEN_SUFFIXES)}")


def read_image(path) -> np.ndarray:
    """Reads an image as linear float32 (H, W, 3): EXR as stored, PNG decoded from sRGB."""
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        import OpenEXR

        with OpenEXR.File(str(path)) as f:
            ch = f.channels()
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, dtype=np.float32)[..., :3]
            if "RGBA" in ch:
                return np.asarray(ch["RGBA"].pixels, dtype=np.float32)[..., :3]
            return np.stack([np.asarray(ch[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)
    if suffix == ".png":
        from PIL import Image

        with Image.open(path) as im:
            if im.mode in ("I;16", "I;16B") or getattr(im, "bits", 8) == 16:
                raise ValueError("16-bit PNG reading is not supported by Pillow; use EXR")
            arr = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
        return srgb_decode(arr).astype(np.float32)
    raise ValueError(f"unsupported image format {suffix!r}: use .exr or .png")


def load_image_map(path, gamma=None, filter_all: float = 0.0, transmit_all: float = 0.0) -> np.ndarray:
    """An ``image_map``'s image as linear RGBFT float64 (H, W, 5), its top row first (semantics
    §5.6). ``gamma``: None, the file's default (EXR and HDR linear; 8-bit formats sRGB-decoded, as
    POV-Ray 3.7 decodes a PNG, measured); "srgb"; or a power. An alpha channel is transmit
    ``1 − alpha`` (straight alpha); ``filter_all`` and ``transmit_all`` are added to every pixel."""
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        import OpenEXR

        with OpenEXR.File(str(path)) as f:
            ch = f.channels()
            key = "RGBA" if "RGBA" in ch else "RGB" if "RGB" in ch else None
            if key is None:
                rgba = np.stack([np.asarray(ch[c].pixels, np.float64) for c in "RGB"], axis=-1)
            else:
                rgba = np.asarray(ch[key].pixels, np.float64)
        linear = gamma is None
    else:
        from PIL import Image

        with Image.open(path) as im:
            im.load()
            rgba = np.asarray(im.convert("RGBA"), np.float64) / 255.0
        linear = suffix == ".hdr" and gamma is None
    rgb, alpha = rgba[..., :3], (rgba[..., 3] if rgba.shape[-1] == 4 else np.ones(rgba.shape[:2]))
    if not linear:
        if gamma is None or gamma == "srgb":
            rgb = srgb_decode(rgb)
        else:
            rgb = np.clip(rgb, 0.0, None) ** float(gamma)
    out = np.zeros(rgb.shape[:2] + (5,))
    out[..., :3] = rgb
    out[..., 3] = filter_all
    out[..., 4] = (1.0 - alpha) + transmit_all
    return out
