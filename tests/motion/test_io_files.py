"""Sequences in one file besides ``.npz``: multi-page TIFF, video, animated GIF; JPEG frames.

Each accepted kind is read back against the frames written in the test; each refused one
gives one line naming the file (docs/data-formats.md).
"""

import sys

import numpy as np
import pytest
from PIL import Image

from replication.errors import InputError
from replication.motion.io import read_sequence
from tests.test_bad_input import MOTION_REFERENCE, assert_refused, redirected, replicate

LUMINANCE = np.array([0.2125, 0.7154, 0.0721])


def grey(t=3, shape=(24, 32), seed=0):
    return np.random.default_rng(seed).random((t, *shape))


def write_video(path, rgb, codec):
    import av

    with av.open(str(path), "w") as container:
        stream = container.add_stream(codec, rate=10)
        stream.width, stream.height = rgb.shape[2], rgb.shape[1]
        stream.pix_fmt = "bgr0" if codec == "ffv1" else "yuv420p"
        for frame in rgb:
            for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)


def test_multi_page_tiff_grey_16_bit(tmp_path):
    import tifffile

    frames = (grey() * 65535).astype(np.uint16)
    tifffile.imwrite(tmp_path / "stack.tif", frames, photometric="minisblack")
    np.testing.assert_allclose(read_sequence(tmp_path / "stack.tif").frames, frames / 65535)


def test_multi_page_tiff_colour_pages_in_order(tmp_path):
    import tifffile

    rgb = (np.random.default_rng(1).random((4, 24, 32, 3)) * 255).astype(np.uint8)
    tifffile.imwrite(tmp_path / "stack.tiff", rgb)
    frames = read_sequence(tmp_path / "stack.tiff").frames
    np.testing.assert_allclose(frames, rgb @ LUMINANCE / 255, atol=1e-12)


@pytest.mark.parametrize("case, message", [
    ("planar", r"page 0: found 3 separate colour planes, shape \(3, 24, 32\)"),
    ("one_page", r"found T = 1 frame\(s\); expected T >= 2"),
    ("shapes", r"page 1: found 24 x 30 pixels; expected the shape of page 0, 24 x 32"),
    ("broken", "cannot be read as a TIFF stack"),
])
def test_tiff_stacks_refused(tmp_path, case, message):
    import tifffile

    path = tmp_path / f"{case}.tif"
    if case == "planar":
        tifffile.imwrite(path, (grey() * 255).astype(np.uint8), photometric="rgb",
                         planarconfig="separate")
    elif case == "one_page":
        tifffile.imwrite(path, grey(1)[0])
    elif case == "shapes":
        with tifffile.TiffWriter(path) as tiff:
            tiff.write(grey(1)[0])
            tiff.write(grey(1, (24, 30))[0])
    else:
        path.write_bytes(b"II*\x00 broken")
    with pytest.raises(InputError, match=message):
        read_sequence(path)


def test_jpeg_frames_are_read_with_a_note(tmp_path, capsys):
    frames = (grey(2) * 255).astype(np.uint8)
    for t, frame in enumerate(frames):
        Image.fromarray(frame).save(tmp_path / f"frame_{t}.jpg", quality=95)
    read = read_sequence(tmp_path).frames
    assert read.shape == (2, 24, 32) and np.abs(read - frames / 255).mean() < 0.05
    assert "JPEG frames are lossy" in capsys.readouterr().err


def test_notes_on_jpeg_data_behind_a_png_suffix_and_mixed_dtypes(tmp_path, capsys):
    """An outside user's JPEG files named .png were read without the lossy note, and float
    TIFF frames (0..255) among 8-bit PNGs only got a brightness warning on the jump."""
    import tifffile

    frames = (grey(4) * 255).astype(np.uint8)
    jpeg = tmp_path / "jpeg"
    jpeg.mkdir()
    for t, frame in enumerate(frames):
        Image.fromarray(frame).save(jpeg / f"frame_{t}.png", format="JPEG", quality=95)
    read_sequence(jpeg)
    assert "lossy (frame_0.png is a JPEG file, whatever its suffix)" in capsys.readouterr().err
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    tifffile.imwrite(mixed / "frame_0.tif", frames[0].astype(np.float32))
    for t, frame in enumerate(frames[1:], 1):
        Image.fromarray(frame).save(mixed / f"frame_{t}.png")
    read_sequence(mixed)
    err = capsys.readouterr().err
    assert "frames of different dtypes (frame_0.tif: float32 TIFF; frame_1.png: uint8 PNG)" \
        in err and "lossy" not in err
    alike = tmp_path / "alike"    # the same dtype in another format: no note
    alike.mkdir()
    tifffile.imwrite(alike / "frame_0.tif", frames[0])
    for t, frame in enumerate(frames[1:], 1):
        Image.fromarray(frame).save(alike / f"frame_{t}.png")
    read_sequence(alike)
    assert "note:" not in capsys.readouterr().err
    (alike / "frame_1.png").unlink()    # 8- and 16-bit frames: both scaled to 0..1
    Image.fromarray(frames[1].astype(np.uint16) * 257).save(alike / "frame_1.png")
    np.testing.assert_allclose(read_sequence(alike).frames[1], frames[1] / 255)
    assert "note:" not in capsys.readouterr().err


@pytest.mark.parametrize("names, noted", [
    ("frame_0 frame_1 frame_2 frame_4", "(most step by 1; frame_2.png -> frame_4.png by 2)"),
    ("frame_0 frame_2 frame_3 frame_4", "(most step by 1; frame_0.png -> frame_2.png by 2)"),
    ("frame_0 frame_2 frame_4 frame_6", None), ("frame_3 frame_4 frame_5 frame_6", None),
    ("f_10 f_11 f_13", "(most step by 1; f_11.png -> f_13.png by 2)"),
    ("a_1 a_1b a_2 a_3", "a_1.png and a_1b.png share the number 1"),
    # a step far beyond the others (counted once, not in a table as long as the step)
    ("t_1 t_2 t_3 t_99999999999", "(most step by 1; t_3.png -> t_99999999999.png by 99999999996)"),
])
def test_note_on_unevenly_numbered_frames(tmp_path, capsys, names, noted):
    """Frames 0, 1, 2, 4 (a dropped frame) were read as evenly spaced, silently; the pair
    named is the one off the most common step."""
    names = names.split()
    for name, frame in zip(names, (grey(len(names)) * 255).astype(np.uint8)):
        Image.fromarray(frame).save(tmp_path / f"{name}.png")
    read_sequence(tmp_path)
    err = capsys.readouterr().err
    assert noted in err if noted else "note:" not in err


def test_animated_gif(tmp_path, capsys):
    frames = (grey(3) * 255).astype(np.uint8)
    images = [Image.fromarray(frame).convert("P") for frame in frames]
    images[0].save(tmp_path / "seq.gif", save_all=True, append_images=images[1:])
    read = read_sequence(tmp_path / "seq.gif").frames
    assert read.shape == (3, 24, 32) and np.abs(read - frames / 255).max() < 0.02
    assert "at most 256 colours" in capsys.readouterr().err


def test_lossless_video_is_exact(tmp_path, capsys):
    rgb = (np.random.default_rng(2).random((3, 24, 32, 3)) * 255).astype(np.uint8)
    write_video(tmp_path / "seq.mkv", rgb, "ffv1")
    np.testing.assert_allclose(read_sequence(tmp_path / "seq.mkv").frames,
                               rgb @ LUMINANCE / 255, atol=1e-12)
    assert "note:" not in capsys.readouterr().err


def test_lossy_video_is_read_with_a_note(tmp_path, capsys):
    smooth = np.clip(grey(5, (32, 48)) * 0.1 + np.linspace(0.2, 0.8, 48), 0, 1)
    rgb = (np.repeat(smooth[..., None], 3, axis=3) * 255).astype(np.uint8)
    write_video(tmp_path / "seq.mp4", rgb, "mpeg4")
    read = read_sequence(tmp_path / "seq.mp4").frames
    assert read.shape == (5, 32, 48) and np.abs(read - smooth).mean() < 0.05
    assert "mpeg4 video is lossy" in capsys.readouterr().err


def test_video_without_pyav_says_how_to_convert(tmp_path, monkeypatch):
    (tmp_path / "seq.mov").write_bytes(b"x")
    monkeypatch.setitem(sys.modules, "av", None)
    with pytest.raises(InputError, match=r"needs PyAV \(pip install av==18.1.0.*ffmpeg -i "
                                         r"VIDEO frames/frame_%05d.png"):
        read_sequence(tmp_path / "seq.mov")


def test_single_image_is_refused(tmp_path):
    Image.fromarray((grey(1)[0] * 255).astype(np.uint8)).save(tmp_path / "one.png")
    with pytest.raises(InputError, match="one.png: a single image; expected a folder of"):
        read_sequence(tmp_path / "one.png")


def test_replicate_reads_a_tiff_stack(tmp_path, capsys):
    import tifffile

    frames = np.load(MOTION_REFERENCE)["frames"]
    stack = tmp_path / "stack.tif"
    tifffile.imwrite(stack, np.round(frames * 65535).astype(np.uint16),
                     photometric="minisblack")
    status, err = replicate(capsys, *redirected("motion_single", tmp_path / "work"),
                            f"data.path={stack}", "method.omega_count=20", "figures=false")
    assert status == 0, err
    assert (tmp_path / "work" / "out" / "result.json").exists()


@pytest.mark.parametrize("name, content, message", [
    ("broken.mp4", b"\x00\x00\x00\x18ftypmp42 broken", "cannot be read as a video"),
    ("broken.gif", b"GIF89a broken", "cannot be read as an animated GIF"),
    ("frame.jpg", None, "a single image"),
])
def test_replicate_refuses_bad_files_with_one_line(tmp_path, capsys, name, content, message):
    data = tmp_path / "data"
    data.mkdir()
    if content is None:
        Image.fromarray((grey(1)[0] * 255).astype(np.uint8)).save(data / name)
    else:
        (data / name).write_bytes(content)
    status, err = replicate(capsys, *redirected("motion_single", tmp_path / "work"),
                            f"data.path={data / name}")
    assert_refused(status, err, message, tmp_path / "work")
