"""Image sequences (docs/data-formats.md): a folder of PNG/TIFF/JPEG frames, one
multi-page TIFF, one video or animated GIF, or one ``.npz``.

The reader refuses bad input with one line naming the file, the field, what was found and
what was expected. Intensities are returned as float64: 8-bit data divided by 255, 16-bit
by 65535, other dtypes unchanged. Lossy input (JPEG frames, most video codecs, GIF's
palette) is read with a ``note:`` line on stderr. The writers are deterministic (same
arrays, same bytes).
"""

from __future__ import annotations

import contextvars
import json
import logging
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from replication.cloth.io import load_npz, write_npz_deterministic
from replication.errors import InputError

FRAME_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg")
JPEG_SUFFIXES = (".jpg", ".jpeg")
TIFF_SUFFIXES = (".tif", ".tiff")
VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov", ".avi", ".mkv", ".webm", ".mpg", ".mpeg", ".wmv",
                  ".ogv", ".gif")
# video codecs that keep every pixel: no note about compression for these
LOSSLESS_CODECS = ("ffv1", "ffvhuff", "huffyuv", "png", "rawvideo", "utvideo", "qtrle")
CONVERT_HINT = ("ffmpeg -i VIDEO frames/frame_%05d.png (then data.path=frames), or save the "
                "frames as a multi-page TIFF")


@dataclass(frozen=True)
class Sequence:
    """An image sequence: ``frames`` (T, H, W) float64, optional ``labels`` (T, H, W) int
    and ``truth`` (the ``truth.json`` object, or None), read from ``source``."""

    frames: np.ndarray
    labels: np.ndarray | None
    truth: dict | None
    source: str
    notes: tuple = ()     # the reader's notes on the input (also printed on stderr)


def _fail(path, field, found, expected):
    raise InputError(f"{path}: {field}: found {found}; expected {expected}")


FULL_SCALE = {"uint8": 255.0, "uint16": 65535.0}   # integer dtypes read as 0..1


def _to_float(path, field, array):
    array = np.asarray(array)
    if array.dtype.name in FULL_SCALE:
        return array.astype(float) / FULL_SCALE[array.dtype.name]
    if array.dtype == np.bool_ or not np.issubdtype(array.dtype, np.number) \
            or np.iscomplexobj(array):
        _fail(path, field, f"dtype {array.dtype}", "real numbers (8- or 16-bit or float)")
    return array.astype(float)


def _luminance(path, image):
    """Colour (H, W, 3|4) to luminance (Rec. 709, as ``skimage.color.rgb2gray``)."""
    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] in (3, 4):
        return image[..., :3] @ np.array([0.2125, 0.7154, 0.0721])
    _fail(path, "shape", f"{image.shape}", "a grey (H, W) or colour (H, W, 3|4) image")
    return image


# the notes of the sequence being read in this thread (read_sequence keeps them)
_NOTES = contextvars.ContextVar("notes", default=None)


def _note(path, text):
    """A remark on input that is read but not exact (lossy compression), on stderr; kept
    for the :class:`Sequence` being read."""
    notes = _NOTES.get()
    if notes is not None:
        notes.append(f"{path}: {text}")
    print(f"note: {path}: {text}", file=sys.stderr, flush=True)


def _reason(error):
    return str(error).splitlines()[0] if str(error) else type(error).__name__


def _pil_array(handle):
    """The pixels of an open Pillow image: 16-bit kept, palette and odd modes to RGB/L."""
    if handle.mode in ("P", "PA", "LA", "1", "CMYK", "YCbCr"):
        handle = handle.convert("L" if handle.mode == "LA" else "RGB")
    image = np.asarray(handle)
    if handle.mode.startswith("I;16"):
        image = image.astype(np.uint16)
    elif handle.mode == "I":
        image = image.astype(np.uint16) if image.max() < 65536 else image
    return image


def read_image(path):
    """One PNG or JPEG (Pillow) or TIFF (tifffile) frame as ``(H, W)`` float64 luminance.

    Parameters
    ----------
    path : str or Path
    """
    return _read_frame(path)[0]


def _read_frame(path):
    """:func:`read_image`'s frame and what the file holds: its format as the reader found
    it (``"PNG"``, ``"JPEG"``, ``"TIFF"``, whatever the suffix says) and its dtype."""
    path = Path(path)
    try:
        if path.suffix.lower() in TIFF_SUFFIXES:
            import tifffile

            image, kind = tifffile.imread(path), "TIFF"
        else:
            from PIL import Image

            with Image.open(path) as handle:
                _check_size(path, (handle.height, handle.width))
                image, kind = _pil_array(handle), handle.format or "image"
    except InputError:
        raise  # a readable frame refused for its size, named as such
    except (OSError, ValueError, SyntaxError) as error:
        raise InputError(f"{path}: cannot be read as an image ({_reason(error)}); expected a "
                         "PNG, TIFF or JPEG frame") from None
    return _luminance(path, _to_float(path, "pixels", image)), (kind, str(image.dtype))


def _read_tiff_stack(path):
    """A multi-page TIFF: page ``t`` is frame ``t``, each page read like a TIFF frame."""
    import tifffile

    images, reason = [], "no readable page"
    logger = logging.getLogger("tifffile")
    level = logger.level
    logger.setLevel(logging.ERROR)  # its warnings on a broken file: our one line says it
    try:
        with tifffile.TiffFile(path) as tiff:
            for index, page in enumerate(tiff.pages):
                _check_size(path, (page.imagelength, page.imagewidth))
                if page.samplesperpixel > 1 and page.planarconfig == 2:
                    _fail(path, f"page {index}", f"{page.samplesperpixel} separate colour "
                          f"planes, shape {page.shape}", "one grey or interleaved-colour "
                          "page per frame (tifffile.imwrite(path, frames, "
                          "photometric='minisblack') writes (T, H, W) so)")
                image = _luminance(path, _to_float(path, f"page {index}", page.asarray()))
                if images and image.shape != images[0].shape:
                    _fail(path, f"page {index}", f"{image.shape[0]} x {image.shape[1]} pixels",
                          f"the shape of page 0, {images[0].shape[0]} x {images[0].shape[1]}")
                images.append(image)
    except (OSError, ValueError) as error:
        if isinstance(error, InputError):
            raise
        images, reason = [], _reason(error)
    finally:
        logger.setLevel(level)
    if not images:
        raise InputError(f"{path}: cannot be read as a TIFF stack ({reason}); expected a "
                         "multi-page TIFF, one page per frame")
    return np.stack(images)


def _read_gif(path):
    """An animated GIF: its frames (Pillow, disposal applied) as luminance."""
    from PIL import Image, ImageSequence

    try:
        with Image.open(path) as handle:
            _check_size(path, (handle.height, handle.width))
            images = [_luminance(path, _to_float(path, f"frame {index}", np.asarray(
                frame.convert("RGB")))) for index, frame in
                enumerate(ImageSequence.Iterator(handle))]
    except (OSError, ValueError, SyntaxError) as error:
        raise InputError(f"{path}: cannot be read as an animated GIF ({_reason(error)}); "
                         f"expected a GIF, or convert it: {CONVERT_HINT}") from None
    _note(path, "GIF frames hold at most 256 colours: the quantisation adds noise to the "
                "image derivatives (lossless frames, PNG or TIFF, are better)")
    return np.stack(images)


def _read_video(path):
    """A video file (PyAV through imageio): its frames in decoding order as luminance."""
    try:
        import av
    except ImportError:
        raise InputError(f"{path}: reading a video needs PyAV (pip install av==18.1.0, as "
                         f"pinned in requirements.lock); or convert it: {CONVERT_HINT}") \
            from None
    import imageio.v3 as iio

    images = []
    try:
        with iio.imopen(path, "r", plugin="pyav") as video:
            codec = video.metadata().get("codec")
            for index, frame in enumerate(video.iter(format="rgb24")):
                if index == 0:
                    _check_size(path, frame.shape[:2])
                images.append(_luminance(path, _to_float(path, f"frame {index}", frame)))
    except (OSError, ValueError, av.FFmpegError) as error:
        if isinstance(error, InputError):
            raise
        raise InputError(f"{path}: cannot be read as a video ({_reason(error)}); expected a "
                         f"video that ffmpeg decodes, or convert it: {CONVERT_HINT}") from None
    if not images:
        _fail(path, "frames", "no video frame", f"a video with frames ({CONVERT_HINT})")
    if codec not in LOSSLESS_CODECS:
        _note(path, f"{codec} video is lossy: compression artefacts add noise to the image "
                    "derivatives (frames are read as 8-bit RGB, then luminance)")
    return np.stack(images)


def _number_order(path):
    """Sort key of a file name with its digit runs read as numbers (frame_2 < frame_10)."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part)
            for part in re.split(r"(\d+)", path.name)]


def _frame_files(folder):
    files = sorted(p for p in folder.iterdir()
                   if p.suffix.lower() in FRAME_SUFFIXES and not p.name.startswith("labels_"))
    labels = sorted(p for p in folder.iterdir()
                    if p.name.startswith("labels_") and p.suffix.lower() == ".png")
    by_number = sorted(files, key=_number_order)
    if by_number != files:
        first = next(i for i, (a, b) in enumerate(zip(files, by_number)) if a != b)
        _note(folder, "frame names hold numbers of different lengths, read in name order "
              f"({files[first].name} before {by_number[first].name}), not number order; pad "
              "the numbers (frame_002.png) if that is not the time order")
    return files, labels


def _check_size(path, shape):
    """Refuse frames of more than ``limits.max_frame_pixels`` pixels, before decoding."""
    from replication.guard import LIMITS

    limit = LIMITS["max_frame_pixels"]
    if len(shape) >= 2 and shape[-2] * shape[-1] > limit:
        _fail(path, "frames", f"frames of {shape[-2]} x {shape[-1]} pixels",
              f"at most limits.max_frame_pixels={limit:.0f} pixels per frame")


MIN_SIDE = 8  # pixels: the smallest frame side the readers take


def check_shape(where, shape):
    """Refuse a generator's frame ``shape`` (H, W) that the readers would refuse.

    Parameters
    ----------
    where : str
        The config key, for the message.
    shape : sequence of int
    """
    from replication.errors import check

    check(len(shape) == 2 and min(int(v) for v in shape) >= MIN_SIDE,
          f"{where}: {list(shape)}; expected [H, W] of at least {MIN_SIDE} pixels each (the "
          "readers refuse smaller frames)")


def _check_frames(path, frames):
    if frames.ndim != 3:
        _fail(path, "frames", f"shape {frames.shape}", "(T, H, W)")
    if frames.shape[0] < 2:
        _fail(path, "frames", f"T = {frames.shape[0]} frame(s)", "T >= 2 frames")
    if frames.shape[1] < MIN_SIDE or frames.shape[2] < MIN_SIDE:
        _fail(path, "frames", f"frames of {frames.shape[1]} x {frames.shape[2]} pixels",
              f"at least {MIN_SIDE} x {MIN_SIDE} pixels")
    finite = np.isfinite(frames)
    if not finite.all():
        t = int(np.nonzero(~finite.reshape(frames.shape[0], -1).all(axis=1))[0][0])
        _fail(path, f"frame {t}", f"{int(np.count_nonzero(~finite))} NaN or inf value(s)",
              "finite intensities")
    ranges = np.ptp(frames, axis=(1, 2))
    if np.any(ranges == 0):
        t = int(np.argmax(ranges == 0))
        _fail(path, f"frame {t}", f"a constant image (all {frames[t].flat[0]:g})",
              "an image with some contrast (the method needs image gradients)")
    # squared gradients of values this small (large) underflow (overflow) in float64
    contrast = float(ranges.max())
    if not 1e-100 <= contrast <= 1e100:
        _fail(path, "frames", f"intensities varying by {contrast:.3g}",
              "a contrast from 1e-100 to 1e100 (rescale the frames, e.g. to 0..1)")


def _read_truth_file(path):
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as error:
        _fail(path, "truth", f"bytes that are not UTF-8 (at byte {error.start})",
              "a UTF-8 JSON file")
    return _parse_truth(path, text)


def _parse_truth(path, text):
    try:
        truth = json.loads(text)
    except json.JSONDecodeError as error:
        _fail(path, "truth", f"invalid JSON ({error.msg})", "a JSON object")
    if not isinstance(truth, dict) or not isinstance(truth.get("objects", []), list):
        _fail(path, "truth", "JSON without an 'objects' list",
              '{"objects": [{"label", "xi", "eta", "omega"}]}')
    if "objects" not in truth and truth:
        _note(path, f"the truth has no 'objects' (keys: {', '.join(sorted(truth))}), so "
              "nothing is scored; expected {\"objects\": [{\"label\", \"xi\", \"eta\", "
              "\"omega\"}]}")
    for item in truth.get("objects", []):
        missing = [k for k in ("xi", "eta", "omega") if not isinstance(item, dict) or k not in item]
        if missing:
            _fail(path, "truth", f"an object without {', '.join(missing)}",
                  "objects with xi, eta and omega")
        label = item.get("label", 0)
        if isinstance(label, bool) or not isinstance(label, int):
            _fail(path, "truth label", f"{json.dumps(label)}", "an integer label value")
        for key in ("xi", "eta", "omega"):
            value = item[key]
            # NaN compares false, an integer beyond float range compares exactly
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not abs(value) <= sys.float_info.max:
                shown = json.dumps(value)
                _fail(path, f"truth {key}", shown if len(shown) <= 40 else shown[:37] + "...",
                      "a finite number")
    return truth


# what Pillow calls JPEG data (MPO: a phone or camera JPEG holding several pictures)
LOSSY_FORMATS = ("JPEG", "MPO")


def _scale(dtype):
    """How :func:`_to_float` scales a dtype: 8- and 16-bit to 0..1, others as stored."""
    return "scaled" if dtype in FULL_SCALE else "as stored"


def _note_frame_kinds(folder, files, kinds):
    """Notes on what the frame files hold: JPEG data (lossy, whatever the suffix says), and
    frames scaled differently (8- and 16-bit frames to 0..1, others read as stored, so a
    float TIFF among 8-bit PNGs can be on another scale)."""
    jpeg = [p for p, (kind, _) in zip(files, kinds)
            if kind in LOSSY_FORMATS or p.suffix.lower() in JPEG_SUFFIXES]
    if jpeg:
        hidden = next((p for p in jpeg if p.suffix.lower() not in JPEG_SUFFIXES), None)
        named = f" ({hidden.name} is a JPEG file, whatever its suffix)" if hidden else ""
        _note(folder, f"JPEG frames are lossy{named}: compression artefacts add noise to the "
                      "image derivatives (lossless frames, PNG or TIFF, are better)")
    first = {}
    for p, (kind, dtype) in zip(files, kinds):
        first.setdefault(_scale(dtype), (p, kind, dtype))
    if len(first) > 1:
        listed = "; ".join(f"{p.name}: {dtype} {kind}" for p, kind, dtype in first.values())
        _note(folder, f"frames of different dtypes ({listed}): 8- and 16-bit frames are "
              "scaled to 0..1, other dtypes read as stored, so their intensities may be on "
              "different scales (a jump the method reads as motion); save every frame alike")


def _note_uneven_numbers(folder, files):
    """A note when the frames' numbers (the last digit run of each name) repeat or are not
    evenly spaced: the methods take frames as equally spaced in time."""
    numbers = [re.findall(r"\d+", p.stem) for p in files]
    if len(files) < 3 or not all(numbers):
        return
    values = [int(found[-1]) for found in numbers]
    if values != sorted(values):
        return  # not in number order: the time order is the names' (docs/data-formats.md)
    steps = np.diff(values)
    if np.any(steps == 0):
        at = int(np.argmax(steps == 0))
        _note(folder, f"{files[at].name} and {files[at + 1].name} share the number "
              f"{values[at]}: both are read, in name order, as frames one step apart")
        return
    unique, counts = np.unique(steps, return_counts=True)
    usual = int(unique[counts.argmax()])   # the most common step (the smallest of ties)
    if np.all(steps == usual):
        return
    odd = [i for i, step in enumerate(steps) if step != usual]
    pairs = ", ".join(f"{files[i].name} -> {files[i + 1].name} by {steps[i]}" for i in odd[:3])
    more = f" and {len(odd) - 3} more" if len(odd) > 3 else ""
    _note(folder, f"frame numbers are not evenly spaced (most step by {usual}; {pairs}{more}): "
          "the methods take frames as equally spaced in time, so a missing frame doubles "
          "the motion between its neighbours")


def _read_folder(folder):
    files, label_files = _frame_files(folder)
    if not files:
        _fail(folder, "frames", "no PNG, TIFF or JPEG file", "frames named in time order "
              "(e.g. frame_000.png, frame_001.png)")
    images, kinds = zip(*(_read_frame(p) for p in files))
    _note_frame_kinds(folder, files, kinds)
    _note_uneven_numbers(folder, files)
    for p, image in zip(files, images):
        if image.shape != images[0].shape:
            _fail(p, "shape", f"{image.shape[0]} x {image.shape[1]} pixels",
                  f"the shape of {files[0].name}, {images[0].shape[0]} x {images[0].shape[1]}")
    frames = np.stack(images) if len(images) > 1 else images[0][None]
    labels = None
    if label_files:
        from PIL import Image

        stack = []
        for p in label_files:
            try:
                with Image.open(p) as handle:
                    _check_size(p, (handle.height, handle.width))
                    stack.append(np.asarray(handle).astype(np.int64))
            except (OSError, ValueError, SyntaxError) as error:
                reason = str(error).splitlines()[0] if str(error) else type(error).__name__
                raise InputError(f"{p}: cannot be read as a label image ({reason}); expected "
                                 "an 8-bit PNG") from None
            if stack[-1].shape != frames.shape[1:]:
                _fail(p, "shape", f"{stack[-1].shape}", f"the frames' shape {frames.shape[1:]}")
        labels = np.stack(stack)
    truth = None
    if (folder / "truth.json").exists():
        truth = _read_truth_file(folder / "truth.json")
    return frames, labels, truth


def _read_npz(path):
    raw = load_npz(path, "an image sequence with a 'frames' key")
    if "frames" not in raw:
        _fail(path, "frames", "no such key (keys: " + ", ".join(sorted(raw)) + ")",
              "a 'frames' array of shape (T, H, W)")
    _check_size(path, raw["frames"].shape)
    frames = _to_float(path, "frames", raw["frames"])
    labels = None
    if "labels" in raw:
        labels = raw["labels"]
        if not np.issubdtype(labels.dtype, np.integer):
            _fail(path, "labels", f"dtype {labels.dtype}", "integer labels (0 = background)")
        labels = labels.astype(np.int64)
    truth = None
    if "truth" in raw:
        text = raw["truth"]
        if text.ndim != 0 or text.dtype.kind not in "US":
            _fail(path, "truth", f"an array of shape {text.shape} and dtype {text.dtype}",
                  "one JSON string (np.array(json.dumps(truth)))")
        text = text.item()
        if isinstance(text, bytes):
            try:
                text = text.decode("utf-8")
            except UnicodeDecodeError as error:
                _fail(path, "truth", f"bytes that are not UTF-8 (at byte {error.start})",
                      "one JSON string")
        truth = _parse_truth(path, text)
    return frames, labels, truth


def read_sequence(path):
    """Read and validate an image sequence: a folder of frames, a multi-page TIFF, a video
    or animated GIF, or an ``.npz`` (docs/data-formats.md).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    Sequence
        ``frames`` of shape (T, H, W), float64.

    Raises
    ------
    InputError
        One line naming the file, the field, what was found and what was expected: no such
        path, unreadable file, fewer than 2 frames, frames of different shapes, a constant
        frame, NaN or inf, labels of the wrong shape, bad truth JSON.
    """
    path = Path(path)
    expected = ("a folder of PNG/TIFF/JPEG frames, a multi-page TIFF, a video, or an .npz "
                "with 'frames' (docs/data-formats.md)")
    if not path.exists():
        raise InputError(f"{path}: no such file or folder; expected {expected}")
    suffix = path.suffix.lower()
    labels = truth = None
    notes = []
    token = _NOTES.set(notes)
    try:
        if path.is_dir():
            frames, labels, truth = _read_folder(path)
        elif suffix == ".npz":
            frames, labels, truth = _read_npz(path)
        elif suffix in TIFF_SUFFIXES:
            frames = _read_tiff_stack(path)
        elif suffix == ".gif":
            frames = _read_gif(path)
        elif suffix in VIDEO_SUFFIXES:
            frames = _read_video(path)
        elif suffix in FRAME_SUFFIXES:
            raise InputError(f"{path}: a single image; expected {expected}: put the frames in "
                             "one folder, named in time order")
        else:
            raise InputError(f"{path}: unsupported file type '{path.suffix}'; expected "
                             f"{expected}")
        _check_frames(path, frames)
        if labels is not None and labels.shape != frames.shape:
            _fail(path, "labels", f"shape {labels.shape}", f"the frames' shape {frames.shape}")
        return Sequence(frames=frames, labels=labels, truth=truth, source=str(path),
                        notes=tuple(notes))
    finally:
        _NOTES.reset(token)


def read_manifest_sequences(path, maker):
    """The ``sequences`` of a data folder's ``manifest.json`` (written by ``replicate
    experiment=MAKER``): ``{name: {"path": str, "role": str, ...}}``, checked.

    Parameters
    ----------
    path : str or Path
        The ``manifest.json``.
    maker : str
        The experiment that writes it, for the message.
    """
    path = Path(path)
    expected = f"the manifest written by `replicate experiment={maker}`"
    if path.parent.is_file():
        raise InputError(f"{path.parent}: a file, not a folder; expected the folder that holds "
                         f"{expected} (manifest.json)")
    if not path.is_file():
        raise InputError(f"{path}: no such file; expected {expected}")
    try:
        manifest = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        reason = str(error).splitlines()[0]
        raise InputError(f"{path}: cannot be read as JSON ({reason}); expected {expected}") \
            from None
    sequences = manifest.get("sequences") if isinstance(manifest, dict) else None
    if not isinstance(sequences, dict):
        found = ("no 'sequences' key" if not isinstance(manifest, dict)
                 or "sequences" not in manifest
                 else f"'sequences' of JSON type {type(sequences).__name__}")
        _fail(path, "sequences", found, expected + " ('sequences': an object, name -> "
              "{'path', 'role'})")
    for name, item in sequences.items():
        if not (isinstance(item, dict) and isinstance(item.get("path"), str)
                and isinstance(item.get("role"), str)):
            _fail(path, f"sequences.{name}", json.dumps(item)[:80],
                  "an object with 'path' and 'role' strings")
        # a path relative to the working directory (the suite's own manifests), else to
        # the manifest's folder (a user's folder, moved about as one piece)
        beside = path.parent / item["path"]
        if not Path(item["path"]).exists() and beside.exists():
            item["path"] = str(beside)
        elif (beside.exists() and not Path(item["path"]).is_absolute()
              and not beside.samefile(item["path"])):
            _note(path, f"sequence {name}: {item['path']} is read from the working "
                  f"directory, not {beside} beside the manifest (give an absolute path, or "
                  "run from the manifest's folder, to read that one)")
    return sequences


def read_listed(sequences, manifest):
    """Read the sequences chosen from a manifest (:func:`read_manifest_sequences`): ``{name:
    Sequence}``. A path found neither from the working directory nor beside the manifest
    is refused naming the manifest and the sequence (sequences not chosen need not exist).

    Parameters
    ----------
    sequences : dict
        ``{name: {"path": str, ...}}``, as :func:`read_manifest_sequences` returns them.
    manifest : str or Path
        The ``manifest.json`` they come from, for the message.
    """
    for name, item in sequences.items():
        if not Path(item["path"]).exists():
            _fail(manifest, f"sequences.{name}.path", f"{item['path']!r}, no such file or "
                  "folder (neither from the working directory nor beside the manifest)",
                  "a sequence's frames (docs/data-formats.md)")
    return {name: read_sequence(item["path"]) for name, item in sequences.items()}


def write_sequence_npz(path, frames, *, labels=None, truth=None):
    """Write a sequence as one deterministic ``.npz`` (float32 frames, uint8 labels).

    Parameters
    ----------
    path : str or Path
    frames : (T, H, W) array_like
    labels : (T, H, W) array_like, optional
        Integer labels (0 = background).
    truth : dict, optional
        Stored as a JSON string.
    """
    arrays = {"frames": np.asarray(frames, dtype=np.float32)}
    if labels is not None:
        arrays["labels"] = np.asarray(labels, dtype=np.uint8)
    if truth is not None:
        arrays["truth"] = np.array(json.dumps(truth, sort_keys=True))
    write_npz_deterministic(path, arrays)


def write_sequence_folder(folder, frames, *, labels=None, truth=None, bits=8):
    """Write a sequence as a folder of grey PNG frames (``frame_000.png``...), label PNGs
    (``labels_000.png``...) and ``truth.json``; intensities in ``[0, 1]`` are rounded to
    ``bits`` (8 or 16) bits. Returns the written paths.

    Parameters
    ----------
    folder : str or Path
    frames : (T, H, W) array_like
        Intensities in ``[0, 1]``.
    labels : (T, H, W) array_like, optional
    truth : dict, optional
    bits : 8 or 16
    """
    from PIL import Image

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    levels, dtype = (255, np.uint8) if bits == 8 else (65535, np.uint16)
    written = []
    for t, frame in enumerate(frames):
        pixels = np.round(np.clip(frame, 0, 1) * levels).astype(dtype)
        target = folder / f"frame_{t:03d}.png"
        Image.fromarray(pixels).save(target, optimize=False, compress_level=6)
        written.append(target)
    if labels is not None:
        for t, label in enumerate(labels):
            target = folder / f"labels_{t:03d}.png"
            Image.fromarray(np.asarray(label, dtype=np.uint8)).save(target, compress_level=6)
            written.append(target)
    if truth is not None:
        target = folder / "truth.json"
        target.write_text(json.dumps(truth, indent=1, sort_keys=True) + "\n")
        written.append(target)
    return written
