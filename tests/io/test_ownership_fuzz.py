"""Issue 36, items 1 and 7: the ownership check under random user edits (hypothesis).

A folder written through :func:`gevsim.io.atomic_dir` (a replaced kind) or :func:`gevsim.io.exclusive` (a
resumed kind: study, dataset) holds a small random tree; a random sequence of user edits is applied inside
it (a file added at any depth, a folder added, a file's bytes changed, a file replaced by a folder or by a
link, a link out of the tree added, a file renamed); then gevsim tries to write there again. Either the
edits changed nothing and gevsim writes, or it is refused with a ConfigError and every entry the user left
(and the file outside the tree a link points to) is still there with its bytes.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gevsim.errors import ConfigError
from gevsim.io import atomic_dir, exclusive
from gevsim.io.mark import MARK
from gevsim.io.staging import LOCK_NAME

NAMES = st.sampled_from(["a", "b", "c.exr", "notes.txt"])
BYTES = st.binary(max_size=6)
PATHS = st.lists(NAMES, min_size=1, max_size=3).map(tuple)
TREES = st.lists(st.tuples(PATHS, BYTES), min_size=1, max_size=5)
EDITS = st.lists(st.tuples(st.sampled_from(["add_file", "add_folder", "modify", "to_folder", "to_link",
                                            "link_out", "rename"]), st.integers(0, 20), NAMES, BYTES),
                 max_size=4)


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root`` (links not followed): a folder, a file and its bytes, a link and its target;
    but a study's lock file, which each run rewrites."""
    found: dict[str, tuple] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            path = Path(dirpath) / name
            rel = str(path.relative_to(root))
            if rel == LOCK_NAME:
                continue
            if path.is_symlink():
                found[rel] = ("link", os.readlink(path))
            elif path.is_dir():
                found[rel] = ("folder",)
            else:
                found[rel] = ("file", path.read_bytes())
    return found


def write_tree(root: Path, tree: list[tuple[tuple[str, ...], bytes]]) -> None:
    """Files at the tree's paths; a path whose folder is already a file (or that is already a folder) is left out."""
    for parts, data in tree:
        path = root.joinpath(*parts)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            if not path.exists():
                path.write_bytes(data)
        except (FileExistsError, NotADirectoryError):
            continue


def apply(root: Path, outside: Path, edits: list[tuple[str, int, str, bytes]]) -> None:
    """The user's edits, each on the entry its number picks (modulo what there is); one that cannot apply is
    left out."""
    for op, pick, name, data in edits:
        listing = snapshot(root)
        files = sorted(p for p, what in listing.items() if what[0] == "file" and p != MARK)
        folders = [""] + sorted(p for p, what in listing.items() if what[0] == "folder")
        folder, file = root / folders[pick % len(folders)], (root / files[pick % len(files)]) if files else None
        if op in ("add_file", "add_folder", "link_out") and not os.path.lexists(folder / name):
            if op == "add_file":
                (folder / name).write_bytes(data)
            elif op == "add_folder":
                (folder / name).mkdir()
            else:
                (folder / name).symlink_to(outside)
        elif file is not None and op == "modify":
            file.write_bytes(data)
        elif file is not None and op in ("to_folder", "to_link"):
            file.unlink()
            file.mkdir() if op == "to_folder" else file.symlink_to(outside)
        elif file is not None and op == "rename" and not os.path.lexists(file.parent / name):
            file.rename(file.parent / name)


def write_again(root: Path, kind: str) -> bool:
    """Whether gevsim wrote its output of ``kind`` into ``root`` again (False: refused with a ConfigError)."""
    try:
        if kind in ("study", "dataset"):
            with exclusive(root, what=kind, kind=kind):
                (root / "report.md").write_text("new report")
        else:
            with atomic_dir(root, kind=kind) as stage:
                (stage / "manifest.json").write_text("{}")
    except ConfigError:
        return False
    return True


def _property(kind: str, tree, edits) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        root, outside = Path(tmp) / "out", Path(tmp) / "secret.txt"
        outside.write_bytes(b"the user's, outside the output")
        if kind in ("study", "dataset"):
            with exclusive(root, what=kind, kind=kind):
                write_tree(root, tree)
        else:
            with atomic_dir(root, kind=kind) as stage:
                write_tree(stage, tree)
        written = snapshot(root)
        apply(root, outside, edits)
        edited = snapshot(root)
        if write_again(root, kind):
            assert edited == written, "gevsim wrote over a folder the user had edited"
        else:
            assert edited != written, "an untouched output was refused"
            assert snapshot(root) == edited  # nothing the user left was deleted, changed or added to
        assert outside.read_bytes() == b"the user's, outside the output"


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["render", "reconstruction", "validation"]), tree=TREES, edits=EDITS)
def test_a_replaced_folder_is_replaced_only_when_no_user_edit_was_made(kind, tree, edits):
    _property(kind, tree, edits)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["study", "dataset"]), tree=TREES, edits=EDITS)
def test_a_study_or_dataset_folder_is_written_into_only_when_no_user_edit_was_made(kind, tree, edits):
    _property(kind, tree, edits)
