"""The one atomic writer (ebb_model.io.output): the target appears only complete, nothing is left behind on an
interruption."""
from __future__ import annotations

import pytest

from ebb_model.errors import OutputError
from ebb_model.io.output import atomic_path


def test_target_is_replaced_only_when_the_block_succeeds(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old")
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and not tmp.exists()
        tmp.write_text("new")
        assert target.read_text() == "old"
    assert target.read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


@pytest.mark.parametrize("exc,raised", [(KeyboardInterrupt, KeyboardInterrupt), (OSError, OutputError)])
def test_interrupted_block_leaves_the_old_file_and_no_temporary(tmp_path, exc, raised):
    """Ctrl-C propagates as it is; a failure to write (an OSError) becomes the typed error naming the target."""
    target = tmp_path / "out.npz"
    target.write_text("old")
    with pytest.raises(raised, match=None if raised is KeyboardInterrupt else r"out\.npz: cannot write"):
        with atomic_path(target, suffix=".npz") as tmp:
            assert tmp.name.endswith(".npz")
            tmp.write_text("half")
            raise exc()
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.npz"]
