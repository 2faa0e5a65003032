"""Fuzz the image input of ``nonrigid track``: every generated set of image files, folders and glob
patterns either loads into a finite float64 stack (and tracks) or gives a TrackingError with a
one-line message; through the command line it exits 0, or 2 with one line on stderr; the files are
never changed and nothing is written beside them.

Inputs: 8- and 16-bit PNG, 1-bit, RGB and RGBA, float32 / float64 TIFF (with NaN / inf), multi-page
TIFF, JPEG, BMP; all-black, all-white and random content; 0-byte, truncated and garbage files;
frames of different sizes, a single frame, images too small to track; unicode folder names;
folders with no image, globs matching nothing, missing files. The default suite runs a fast
subset; ``-m slow`` runs >= 600 inputs and prints the tally.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, strategies as st

from tests._fuzz_util import Tally, fixed, one_line, run_cli, snapshot
from tracking import TrackingError
from tracking._images import load_images

KINDS = ("png8", "png16", "png1", "rgb", "rgba", "tif32", "tif64", "tifpages", "jpg", "bmp")
SUFFIX = {"png8": ".png", "png16": ".png", "png1": ".png", "rgb": ".png", "rgba": ".png", "tif32": ".tif",
          "tif64": ".tiff", "tifpages": ".tif", "jpg": ".jpg", "bmp": ".bmp"}
SIZES = ((4, 4), (7, 30), (16, 16), (16, 20), (24, 24), (32, 32))

_name = st.text(st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="/\\*?[]"), min_size=1,
                max_size=10).filter(lambda s: s not in (".", "..") and len(s.encode()) < 200)
_frame = st.fixed_dictionaries({
    "kind": st.sampled_from(KINDS), "size": st.sampled_from(SIZES),
    "content": st.sampled_from(("black", "white", "random", "nan", "inf")),
    "damage": st.one_of(st.just(None), st.just("empty"), st.just("garbage"), st.just("suffix"),
                        st.tuples(st.just("truncate"), st.floats(0, 0.95)))})
cases = st.tuples(_name, st.lists(_frame, min_size=0, max_size=3),
                  st.sampled_from(("files", "folder", "glob", "glob-nothing", "missing", "files+missing")),
                  st.integers(0, 2 ** 16))


def pixels(frame: dict, seed: int) -> np.ndarray:
    rows, cols = frame["size"]
    kind, content = frame["kind"], frame["content"]
    top = {"png16": 65535, "png1": 1}.get(kind, 1.0 if kind.startswith("tif") else 255)
    a = {"black": np.zeros((rows, cols)), "white": np.full((rows, cols), float(top))}.get(content)
    if a is None:
        a = np.random.default_rng(seed).random((rows, cols)) * top
        if content in ("nan", "inf") and kind.startswith("tif"):
            a[rows // 2, cols // 2] = np.nan if content == "nan" else np.inf
    if kind in ("rgb", "rgba"):
        a = np.repeat(a[..., None], 3 if kind == "rgb" else 4, axis=2)
    dtype = {"png16": np.uint16, "tif32": np.float32, "tif64": np.float64, "tifpages": np.float32}.get(kind, np.uint8)
    return a.astype(dtype) if dtype != np.uint8 else np.clip(a, 0, 255).astype(np.uint8)


def write_frame(path: Path, frame: dict, seed: int) -> Path:
    import cv2
    import tifffile
    from PIL import Image

    kind = frame["kind"]
    a = pixels(frame, seed)
    path = path.with_suffix(SUFFIX[kind])
    if kind.startswith("tif"):
        tifffile.imwrite(str(path), np.stack([a, a]) if kind == "tifpages" else a, photometric="minisblack")
    elif kind == "png1":
        Image.fromarray(a.astype(bool)).save(path)
    else:
        ok, data = cv2.imencode(SUFFIX[kind], a)
        path.write_bytes(data.tobytes())
    damage = frame["damage"]
    data = path.read_bytes()
    if damage == "empty":
        path.write_bytes(b"")
    elif damage == "garbage":
        path.write_bytes(np.random.default_rng(seed).bytes(64))
    elif damage == "suffix":  # the bytes of one format under another format's name
        path = path.rename(path.with_suffix(".png" if path.suffix != ".png" else ".jpg"))
    elif damage is not None:
        path.write_bytes(data[:int(damage[1] * len(data))])
    return path


def sources(root: Path, name: str, frames: list[dict], mode: str, seed: int) -> tuple[Path, list[str]]:
    """Write the frames in folder ``root/in/name``; the command-line sources that name them."""
    folder = root / "in" / name
    folder.mkdir(parents=True)
    paths = [write_frame(folder / f"frame_{k + 1}", f, seed + k) for k, f in enumerate(frames)]
    if mode == "folder":
        return folder, [str(folder)]
    if mode == "glob":
        return folder, [str(folder / "frame_*")]
    if mode == "glob-nothing":
        return folder, [str(folder / "nothing_*.png")]
    if mode == "missing":
        return folder, [str(folder / "missing.png")]
    if mode == "files+missing":
        return folder, [str(p) for p in paths] + [str(folder / "missing.tif")]
    return folder, [str(p) for p in paths]


def check_case(name, frames, mode, seed, tally: Tally, cli: bool):
    root = Path(tempfile.mkdtemp(prefix="fuzz-images-"))
    try:
        folder, given_sources = sources(root, name, frames, mode, seed)
        before = snapshot(root / "in")
        outcome, message = "ok", ""
        try:
            stack = load_images(given_sources)
            if stack.dtype != np.float64 or stack.ndim != 3 or not np.all(np.isfinite(stack)):
                outcome, message = "traceback", f"stack {stack.dtype} {stack.shape}"
        except TrackingError as e:
            outcome, message = ("error" if one_line(str(e)) else "traceback"), str(e)
        except Exception as e:  # noqa: BLE001 - the failure this suite looks for
            outcome, message = "traceback", f"{type(e).__name__}: {e}"
        if cli and outcome != "traceback":
            rc, err = run_cli(["track", "--pattern", "speckle", "--scale", "0.1", "--spacing", "8", "--subset", "7",
                               "--search", "2", *given_sources, "--out", str(root / "out" / "bundle")])
            if not (rc == 0 or (rc == 2 and one_line(err) and err.startswith("nonrigid track: error: "))):
                outcome, message = "traceback", f"track: exit {rc}: {err!r}"
        if snapshot(root / "in") != before:
            outcome = "modified"
        tally[outcome] += 1
        assert outcome in ("ok", "error"), (frames, mode, message if outcome != "modified" else "files changed")
    finally:
        shutil.rmtree(root, ignore_errors=True)


def test_good_images_load():
    """Two random 8-bit frames load and track: the fuzz starts from something that works."""
    tally = Tally()
    frame = {"kind": "png8", "size": (32, 32), "content": "random", "damage": None}
    check_case("base", [frame, frame], "files", 1, tally, cli=True)
    assert tally["ok"] == 1


FAST, SLOW = Tally(), Tally()


@fixed(80)
@given(cases)
def test_fuzz_images_fast(case):
    check_case(*case, FAST, cli=case[3] % 4 == 0)


@pytest.mark.slow
def test_fuzz_images_slow():
    """>= 600 generated inputs (with test_fuzz_bundles' slow test, >= 2,000); prints the tally."""
    @fixed(600)
    @given(cases)
    def run(case):
        check_case(*case, SLOW, cli=case[3] % 2 == 0)

    run()
    print(SLOW.line("images"))
    assert sum(SLOW.values()) >= 600 and SLOW["traceback"] == SLOW["modified"] == 0
