"""Capture sessions: pairs written at once, manifest, reopening, plain folders, failures."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.files import session as session_mod
from stereo_gui.files.session import MANIFEST, CameraIds, CaptureSession

SIZE = (64, 48)  # small images: the point is the files, not the pixels


def _img(seed: int, size=SIZE) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (size[1], size[0], 3), np.uint8)


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


def _new(tmp_path, **kw):
    return CaptureSession.create(tmp_path / "s", BoardSpec(9, 6, 25.0), SIZE,
                                 CameraIds("USB cam (0)", "USB cam (2)"), **kw)


def test_create_writes_a_manifest(tmp_path):
    s = _new(tmp_path)
    data = json.loads((tmp_path / "s" / MANIFEST).read_text())
    assert data["format_version"] == session_mod.FORMAT_VERSION
    assert data["board"] == {"cols": 9, "rows": 6, "square_mm": 25.0}
    assert data["resolution"] == [64, 48]
    assert data["cameras"] == {"left": "USB cam (0)", "right": "USB cam (2)"}
    assert data["pairs"] == [] and data["excluded"] == []
    assert s.pairs == ()


def test_pairs_are_written_at_once_and_read_back_exactly(tmp_path):
    s = _new(tmp_path)
    e1 = s.add_pair(_img(1), _img(2), time="2026-11-22T10:00:00.000+00:00")
    # on disk before anything else happens: both images and the manifest entry
    assert e1.left.name == "chessboard-L1.png" and e1.right.name == "chessboard-R1.png"
    np.testing.assert_array_equal(cv2.imread(str(e1.left)), _img(1))
    np.testing.assert_array_equal(cv2.imread(str(e1.right)), _img(2))
    data = json.loads(s.manifest_path.read_text())
    assert data["pairs"] == [{"name": e1.name, "number": 1, "left": "chessboard-L1.png",
                              "right": "chessboard-R1.png",
                              "time": "2026-11-22T10:00:00.000+00:00"}]
    e2 = s.add_pair(_img(3), _img(4))
    assert e2.number == 2 and e2.time
    assert _files(tmp_path / "s") == ["chessboard-L1.png", "chessboard-L2.png", "chessboard-R1.png",
                                      "chessboard-R2.png", MANIFEST]


def test_reopen_continues_numbering_and_keeps_exclusions(tmp_path):
    s = _new(tmp_path)
    names = [s.add_pair(_img(i), _img(i + 10)).name for i in range(3)]
    s.set_excluded(names[1], True)
    s.delete_pair(names[2])
    assert not (tmp_path / "s" / "chessboard-L3.png").exists()

    again = CaptureSession.open(tmp_path / "s")
    assert again.warnings == []
    assert [p.name for p in again.pairs] == names[:2]
    assert [p.name for p in again.included_pairs()] == [names[0]]
    assert again.board == BoardSpec(9, 6, 25.0) and again.resolution == SIZE
    assert again.cameras == CameraIds("USB cam (0)", "USB cam (2)")
    # the next number follows the highest ever kept, never reusing a file name on disk
    e = again.add_pair(_img(7), _img(8))
    assert e.number == 3 and e.left.name == "chessboard-L3.png"
    again.set_excluded(names[1], False)
    assert len(CaptureSession.open(tmp_path / "s").included_pairs()) == 3


def test_numbers_never_overwrite_unknown_files(tmp_path):
    s = _new(tmp_path)
    s.add_pair(_img(1), _img(2))
    stray = tmp_path / "s" / "chessboard-L2.png"
    stray.write_bytes(b"someone else's file")
    e = s.add_pair(_img(3), _img(4))
    assert e.number == 3
    assert stray.read_bytes() == b"someone else's file"


@pytest.mark.parametrize("naming", [("chessboard-L{n}.png", "chessboard-R{n}.png"),
                                    ("left{n}.jpg", "right{n}.jpg")])
def test_folder_without_manifest_opens(tmp_path, naming):
    folder = tmp_path / "report"
    folder.mkdir()
    for n in (1, 2, 5):
        cv2.imwrite(str(folder / naming[0].format(n=n)), _img(n))
        cv2.imwrite(str(folder / naming[1].format(n=n)), _img(n + 10))
    s = CaptureSession.open(folder)
    assert len(s.pairs) == 3 and not s.has_manifest
    assert not (folder / MANIFEST).exists()  # opening alone changes nothing
    assert s.resolution == SIZE
    assert [p.left.name for p in s.pairs] == [naming[0].format(n=n) for n in (1, 2, 5)]
    # the first change writes the manifest; new pairs continue after the highest number
    e = s.add_pair(_img(20), _img(21))
    assert e.number == 6
    assert s.has_manifest and (folder / MANIFEST).exists()
    assert len(CaptureSession.open(folder).pairs) == 4


def test_images_saved_without_manifest_entry_are_picked_up(tmp_path):
    s = _new(tmp_path)
    s.add_pair(_img(1), _img(2))
    # a crash after the images, before the manifest: the pair must not be lost
    cv2.imwrite(str(tmp_path / "s" / "chessboard-L2.png"), _img(3))
    cv2.imwrite(str(tmp_path / "s" / "chessboard-R2.png"), _img(4))
    again = CaptureSession.open(tmp_path / "s")
    assert [p.number for p in again.pairs] == [1, 2]
    assert any("not in the manifest" in w for w in again.warnings)


def test_listed_pair_with_missing_images_is_left_out_with_a_warning(tmp_path):
    s = _new(tmp_path)
    s.add_pair(_img(1), _img(2))
    e = s.add_pair(_img(3), _img(4))
    e.right.unlink()
    again = CaptureSession.open(tmp_path / "s")
    assert [p.number for p in again.pairs] == [1]
    assert any("missing" in w for w in again.warnings)


def test_corrupt_manifest_falls_back_to_the_images(tmp_path):
    s = _new(tmp_path)
    s.add_pair(_img(1), _img(2))
    s.manifest_path.write_text("{ broken")
    again = CaptureSession.open(tmp_path / "s")
    assert len(again.pairs) == 1 and again.warnings


def test_unreadable_manifest_is_kept_aside_when_the_session_changes(tmp_path):
    """Saving a pair into a session whose session.json could not be read must not overwrite
    that file: its board and exclusions are only in there."""
    s = _new(tmp_path)
    s.add_pair(_img(1), _img(2))
    s.manifest_path.write_text('{"format_version": 1, "excluded": ["chessboard-1"], ')
    again = CaptureSession.open(tmp_path / "s")
    assert f"{MANIFEST}.unreadable" in again.warnings[0]
    again.add_pair(_img(3), _img(4))
    kept = tmp_path / "s" / f"{MANIFEST}.unreadable"
    assert kept.read_text() == '{"format_version": 1, "excluded": ["chessboard-1"], '
    assert [p.number for p in CaptureSession.open(tmp_path / "s").pairs] == [1, 2]


def test_missing_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        CaptureSession.open(tmp_path / "nope")


def test_create_refuses_an_existing_session(tmp_path):
    _new(tmp_path)
    with pytest.raises(InputError, match="already holds"):
        _new(tmp_path)


def test_wrong_sizes_are_refused_before_writing(tmp_path):
    s = _new(tmp_path)
    with pytest.raises(InputError, match="same size"):
        s.add_pair(_img(1), _img(2, (32, 24)))
    with pytest.raises(InputError, match="does not fit"):
        s.add_pair(_img(1, (32, 24)), _img(2, (32, 24)))
    assert _files(tmp_path / "s") == [MANIFEST]


@pytest.mark.parametrize("fail_at", [1, 2, 3])  # left image, right image, manifest
def test_full_disk_loses_nothing_already_saved(tmp_path, monkeypatch, fail_at):
    s = _new(tmp_path)
    first = s.add_pair(_img(1), _img(2))
    before = {p: (tmp_path / "s" / p).read_bytes() for p in _files(tmp_path / "s")}
    from disk_faults import install

    install(monkeypatch, "write", fail_at)  # a real full disk: half the data, then ENOSPC
    with pytest.raises(InputError, match="(?i)no space left"):
        s.add_pair(_img(3), _img(4))
    after = {p: (tmp_path / "s" / p).read_bytes() for p in _files(tmp_path / "s")}
    assert after == before  # same files, same bytes, no half pair, no temp file
    assert s.pairs == (first,)
    monkeypatch.undo()
    assert s.add_pair(_img(3), _img(4)).number == 2


def test_vanished_folder_raises_input_error(tmp_path):
    s = _new(tmp_path)
    for p in (tmp_path / "s").iterdir():
        p.unlink()
    (tmp_path / "s").rmdir()
    with pytest.raises(InputError):
        s.add_pair(_img(1), _img(2))
    assert s.pairs == ()


def test_unknown_pair_name(tmp_path):
    s = _new(tmp_path)
    with pytest.raises(InputError, match="no pair named"):
        s.set_excluded("chessboard-999", True)


def test_subfolder_layout_opens_and_names_match_discovery(tmp_path):
    from stereo_gui.files.pairs import discover_pairs

    folder = tmp_path / "sub"
    for side in ("left", "right"):
        (folder / side).mkdir(parents=True)
        for n in (1, 2):
            cv2.imwrite(str(folder / side / f"{n:06d}.png"), _img(n))
    cv2.imwrite(str(folder / "left" / "000003.png"), _img(3))  # no right partner
    s = CaptureSession.open(folder)
    assert [p.name for p in s.pairs] == [p.name for p in discover_pairs(folder).pairs]
    assert any("unpaired" in w for w in s.warnings)
    # a session's own pairs get the names discovery gives their files
    t = _new(tmp_path)
    e = t.add_pair(_img(1), _img(2))
    assert [p.name for p in discover_pairs(t.folder).pairs] == [e.name]


def test_a_manifest_path_outside_the_folder_is_refused_and_never_deleted(tmp_path):
    """A manifest naming `"left": "../victim.txt"` must not let Delete pair remove it."""
    import json

    s = _new(tmp_path)
    s.add_pair(_img(1), _img(2))
    victim = tmp_path / "victim.txt"
    victim.write_text("not yours")
    manifest = tmp_path / "s" / MANIFEST
    doc = json.loads(manifest.read_text())
    doc["pairs"][0]["left"] = "../victim.txt"
    manifest.write_text(json.dumps(doc))
    opened = CaptureSession.open(tmp_path / "s")
    assert any("not a file inside the session folder" in w for w in opened.warnings)
    for p in opened.pairs:
        assert victim.resolve() not in (p.left.resolve(), p.right.resolve())
        opened.delete_pair(p.name)
    assert victim.read_text() == "not yours"


def test_an_entry_pointing_outside_is_left_out_alone(tmp_path):
    """A manifest with one entry pointing outside keeps the rest, its exclusions too (calibrate
    does not take an excluded pair again): only that entry goes, and the warning names it; the
    manifest is kept aside when the session changes."""
    s = _new(tmp_path)
    for i in range(4):
        s.add_pair(_img(i), _img(10 + i))
    s.set_excluded("chessboard-2", True)
    (tmp_path / "outside.png").write_bytes((tmp_path / "s" / "chessboard-L1.png").read_bytes())
    manifest = tmp_path / "s" / MANIFEST
    doc = json.loads(manifest.read_text())
    doc["pairs"][3]["left"] = "../outside.png"  # chessboard-4
    doc["pairs"][2]["number"] = 1  # chessboard-3 says it is number 1 too
    original = json.dumps(doc)
    manifest.write_text(original)
    opened = CaptureSession.open(tmp_path / "s")
    said = [w for w in opened.warnings if "that entry is left out" in w]
    assert len(said) == 2
    assert "pairs entry 4 (chessboard-4) left '../outside.png'" in said[0] + said[1]
    assert "number 1 is listed twice" in said[0] + said[1]
    by_name = {p.name: p for p in opened.pairs}
    assert by_name["chessboard-2"].excluded and not by_name["chessboard-1"].excluded
    assert opened.board == BoardSpec(9, 6, 25.0) and opened.resolution == SIZE
    for p in opened.pairs:  # the images in the folder are still found: none outside
        assert (tmp_path / "s") in p.left.resolve().parents
    opened.set_excluded("chessboard-1", True)  # a change: the manifest as it was is kept
    assert (tmp_path / "s" / f"{MANIFEST}.unreadable").read_text() == original
    again = CaptureSession.open(tmp_path / "s")
    assert {p.name for p in again.pairs if p.excluded} == {"chessboard-1", "chessboard-2"}


def test_delete_pair_refuses_a_file_outside_the_folder(tmp_path):
    """A pair's image replaced, after the session was opened, by a link to a file elsewhere."""
    s = _new(tmp_path)
    entry = s.add_pair(_img(1), _img(2))
    victim = tmp_path / "victim.txt"
    victim.write_text("not yours")
    entry.left.unlink()
    entry.left.symlink_to(victim)
    with pytest.raises(InputError, match="not inside the session folder"):
        s.delete_pair(entry.name)
    assert victim.exists() and entry.left.is_symlink() and entry.right.exists()


@pytest.mark.parametrize(("doc", "message"), [
    ([1, 2, 3], "JSON list, not an object"),
    ({"format_version": 1, "pairs": [{"name": "a", "number": -1, "left": "l", "right": "r"}]},
     "number is -1"),
    ({"format_version": 1, "pairs": [{"name": "a", "number": 1, "left": "l1", "right": "r1"},
                                     {"name": "b", "number": 1, "left": "l2", "right": "r2"}]},
     "listed twice"),
    ({"format_version": 1, "resolution": [99999999999, 480]}, "resolution width"),
    ({"format_version": 1, "board": {"cols": 9, "rows": 6, "square_mm": 1e308}}, "board"),
    ({"format_version": 1, "pairs": "x"}, "pairs should be a list"),
])
def test_bad_manifests_are_reported_by_field_and_the_folder_still_opens(tmp_path, doc, message):
    import json

    folder = tmp_path / "s"
    folder.mkdir()
    (folder / MANIFEST).write_text(json.dumps(doc))
    s = CaptureSession.open(folder)
    assert any(message in w for w in s.warnings), s.warnings
