"""The sequence reader: formats of docs/data-formats.md, and one test per refused input."""

import json

import numpy as np
import pytest
from PIL import Image

from replication.errors import InputError
from replication.motion.io import read_sequence, write_sequence_folder, write_sequence_npz


def frames_like(t=2, shape=(16, 16), seed=0):
    return np.random.default_rng(seed).random((t, *shape))


def write_png(path, array):
    Image.fromarray(np.asarray(array)).save(path)


def test_npz_round_trip(tmp_path):
    frames = frames_like(3)
    truth = {"objects": [{"label": 1, "xi": 1.0, "eta": 2.0, "omega": 0.01}]}
    labels = np.zeros((3, 16, 16), dtype=np.uint8)
    write_sequence_npz(tmp_path / "s.npz", frames, labels=labels, truth=truth)
    sequence = read_sequence(tmp_path / "s.npz")
    np.testing.assert_allclose(sequence.frames, frames, atol=1e-7)
    assert sequence.truth == truth and sequence.labels.shape == (3, 16, 16)


def test_npz_writer_is_deterministic(tmp_path):
    write_sequence_npz(tmp_path / "a.npz", frames_like())
    write_sequence_npz(tmp_path / "b.npz", frames_like())
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()


@pytest.mark.parametrize("bits", [8, 16])
def test_folder_round_trip(tmp_path, bits):
    frames = frames_like()
    write_sequence_folder(tmp_path, frames, labels=np.ones((2, 16, 16)), bits=bits,
                          truth={"objects": []})
    sequence = read_sequence(tmp_path)
    np.testing.assert_allclose(sequence.frames, frames, atol=0.51 / (2 ** bits - 1))
    assert sequence.labels.shape == (2, 16, 16)


def test_colour_frames_become_luminance(tmp_path):
    rgb = (np.random.default_rng(1).random((2, 16, 16, 3)) * 255).astype(np.uint8)
    for t in range(2):
        write_png(tmp_path / f"f{t}.png", rgb[t])
    sequence = read_sequence(tmp_path)
    expected = rgb[0] @ np.array([0.2125, 0.7154, 0.0721]) / 255
    np.testing.assert_allclose(sequence.frames[0], expected, atol=1e-12)


def test_tiff_frames(tmp_path):
    import tifffile

    frames = (frames_like() * 65535).astype(np.uint16)
    for t in range(2):
        tifffile.imwrite(tmp_path / f"f{t}.tif", frames[t])
    np.testing.assert_allclose(read_sequence(tmp_path).frames, frames / 65535)


def test_refuses_missing_path(tmp_path):
    with pytest.raises(InputError, match="no such file or folder"):
        read_sequence(tmp_path / "absent.npz")


def test_refuses_one_frame(tmp_path):
    np.savez(tmp_path / "one.npz", frames=frames_like(1))
    with pytest.raises(InputError,
                       match=r"one.npz: frames: found T = 1 frame\(s\); expected T >= 2"):
        read_sequence(tmp_path / "one.npz")


def test_refuses_one_frame_in_a_folder(tmp_path):
    write_png(tmp_path / "f0.png", (frames_like(1)[0] * 255).astype(np.uint8))
    with pytest.raises(InputError, match="T = 1 frame"):
        read_sequence(tmp_path)


def test_refuses_mismatched_shapes(tmp_path):
    write_png(tmp_path / "f0.png", (frames_like(1)[0] * 255).astype(np.uint8))
    write_png(tmp_path / "f1.png", (frames_like(1, (16, 20))[0] * 255).astype(np.uint8))
    with pytest.raises(InputError, match=r"f1.png: shape: found 16 x 20 pixels; expected the "
                                         r"shape of f0.png, 16 x 16"):
        read_sequence(tmp_path)


def test_refuses_constant_frame(tmp_path):
    frames = frames_like()
    frames[1] = 0.25
    np.savez(tmp_path / "c.npz", frames=frames)
    with pytest.raises(InputError, match="frame 1: found a constant image"):
        read_sequence(tmp_path / "c.npz")


@pytest.mark.parametrize("scale", [1e-160, 1e160])
def test_refuses_intensities_whose_squared_gradients_underflow_or_overflow(tmp_path, scale):
    np.savez(tmp_path / "s.npz", frames=frames_like() * scale)
    with pytest.raises(InputError, match="expected a contrast from 1e-100 to 1e100"):
        read_sequence(tmp_path / "s.npz")
    np.savez(tmp_path / "ok.npz", frames=frames_like() * scale ** 0.5)
    assert read_sequence(tmp_path / "ok.npz").frames.shape[0] >= 2


def test_refuses_nan(tmp_path):
    frames = frames_like()
    frames[0, 3, 4] = np.nan
    np.savez(tmp_path / "n.npz", frames=frames)
    with pytest.raises(InputError, match="frame 0: found 1 NaN or inf value"):
        read_sequence(tmp_path / "n.npz")


def test_refuses_missing_frames_key(tmp_path):
    np.savez(tmp_path / "k.npz", images=frames_like())
    with pytest.raises(InputError, match="frames: found no such key"):
        read_sequence(tmp_path / "k.npz")


def test_refuses_wrong_dimensions(tmp_path):
    np.savez(tmp_path / "d.npz", frames=np.zeros((2, 16)))
    with pytest.raises(InputError, match=r"frames: found shape \(2, 16\); expected \(T, H, W\)"):
        read_sequence(tmp_path / "d.npz")


def test_refuses_unsupported_file(tmp_path):
    (tmp_path / "movie.xyz").write_bytes(b"x")
    with pytest.raises(InputError, match="unsupported file type '.xyz'"):
        read_sequence(tmp_path / "movie.xyz")


def test_refuses_bad_truth(tmp_path):
    np.savez(tmp_path / "t.npz", frames=frames_like(), truth=np.array("{not json"))
    with pytest.raises(InputError, match="truth: found invalid JSON"):
        read_sequence(tmp_path / "t.npz")
    np.savez(tmp_path / "u.npz", frames=frames_like(),
             truth=np.array(json.dumps({"objects": [{"xi": 1}]})))
    with pytest.raises(InputError, match="an object without eta, omega"):
        read_sequence(tmp_path / "u.npz")


def test_refuses_labels_of_another_shape(tmp_path):
    np.savez(tmp_path / "l.npz", frames=frames_like(), labels=np.zeros((2, 8, 8), np.uint8))
    with pytest.raises(InputError, match=r"labels: found shape \(2, 8, 8\)"):
        read_sequence(tmp_path / "l.npz")


def test_notes_on_unpadded_frame_numbers_and_a_truth_without_objects(tmp_path, capsys):
    """Both read as the docs say (name order; nothing scored), with a note: an outside
    user's frame_0..frame_11 went in the order 0, 1, 10, 11, 2, ... and a misspelt
    'object' key lost the scoring, both silently."""
    folder = tmp_path / "seq"
    folder.mkdir()
    for i, frame in enumerate(frames_like(11)):
        write_png(folder / f"frame_{i}.png", (frame * 255).astype(np.uint8))
    read_sequence(folder)
    assert "(frame_10.png before frame_2.png), not number order" in capsys.readouterr().err
    padded = tmp_path / "padded"
    write_sequence_folder(padded, frames_like(11))
    (padded / "truth.json").write_text(json.dumps({"object": [{"xi": 1}]}))
    sequence = read_sequence(padded)
    err = capsys.readouterr().err
    assert "number order" not in err and "the truth has no 'objects' (keys: object)" in err
    assert sequence.truth == {"object": [{"xi": 1}]}


def test_a_png_frame_over_the_pixel_limit_is_named_as_too_large(tmp_path, monkeypatch):
    """It read as 'cannot be read as an image', as if the file were broken."""
    from replication.guard import LIMITS

    for t in range(2):
        Image.fromarray(np.full((40, 40), 60 * t, np.uint8)).save(tmp_path / f"f{t}.png")
    monkeypatch.setitem(LIMITS, "max_frame_pixels", 1000)
    with pytest.raises(InputError, match="found frames of 40 x 40 pixels; expected at most "
                                         "limits.max_frame_pixels=1000"):
        read_sequence(tmp_path)


def test_a_manifest_path_is_found_beside_the_manifest(tmp_path, monkeypatch, capsys):
    """A user's sequences folder names its sequences relative to itself; the suite's own
    manifests name them relative to the repository (the working directory), which wins,
    with a note when the manifest's folder has another file of that name."""
    from replication.motion.io import read_manifest_sequences

    folder = tmp_path / "mine"
    (folder / "seq").mkdir(parents=True)
    (folder / "manifest.json").write_text(json.dumps(
        {"sequences": {"a": {"path": "seq", "role": "accuracy"},
                       "b": {"path": "gone", "role": "accuracy"}}}))
    monkeypatch.chdir(tmp_path)
    sequences = read_manifest_sequences(folder / "manifest.json", "motion_data")
    assert sequences["a"]["path"] == str(folder / "seq")
    assert sequences["b"]["path"] == "gone"   # left as given: its reader names it
    assert capsys.readouterr().err == ""
    (tmp_path / "seq").mkdir()
    sequences = read_manifest_sequences(folder / "manifest.json", "motion_data")
    assert sequences["a"]["path"] == "seq"
    assert f"seq is read from the working directory, not {folder / 'seq'}" in (
        capsys.readouterr().err)
    monkeypatch.chdir(folder)   # the same file both ways: no note
    read_manifest_sequences("manifest.json", "motion_data")
    assert capsys.readouterr().err == ""


def test_the_readers_notes_are_kept_with_the_sequence(tmp_path):
    """The note on frames read out of number order reached stderr only: result.json, which
    outside checks read, had no word of it. The sequence keeps its notes (motion_single and
    segment_multi write them among their warnings); a clean read has none."""
    folder = tmp_path / "seq"
    folder.mkdir()
    for i, frame in enumerate(frames_like(11)):
        write_png(folder / f"frame_{i}.png", (frame * 255).astype(np.uint8))
    notes = read_sequence(folder).notes
    assert len(notes) == 1 and "(frame_10.png before frame_2.png)" in notes[0]
    write_sequence_folder(tmp_path / "padded", frames_like(11))
    assert read_sequence(tmp_path / "padded").notes == ()
