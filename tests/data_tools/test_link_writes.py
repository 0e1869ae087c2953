"""save_volume through links: a loop is refused, not replaced by a file; a plain volume through a
link beside its target rewrites the target's stale sidecar."""
import os

import numpy as np
import pytest

from data_tools import InputError, Volume
from data_tools.io import load_volume, save_volume


@pytest.mark.parametrize("ext", [".npy", ".nrrd", ".mhd"])
@pytest.mark.parametrize("loop", [1, 2])
def test_a_link_in_a_loop_is_refused_not_replaced(tmp_path, ext, loop):
    vol = Volume(np.zeros((2, 2, 2), np.uint8))
    a, b = tmp_path / f"a{ext}", tmp_path / f"b{ext}"
    if loop == 1:
        os.symlink(a.name, a)
    else:
        os.symlink(b.name, a)
        os.symlink(a.name, b)
    with pytest.raises(InputError, match="a link in a loop"):
        save_volume(vol, a)
    assert a.is_symlink() and (loop == 1 or b.is_symlink())


def test_a_plain_volume_through_a_link_beside_its_target_rewrites_the_targets_sidecar(tmp_path):
    placed = Volume(np.arange(8, dtype=np.uint8).reshape(2, 2, 2), spacing=(1, 2, 3))
    plain = Volume(np.arange(8, dtype=np.uint8).reshape(2, 2, 2))
    real, link = tmp_path / "real.npy", tmp_path / "link.npy"
    save_volume(placed, real)
    os.symlink(real.name, link)
    save_volume(plain, link)
    assert load_volume(real).spacing == (1.0, 1.0, 1.0) == load_volume(link).spacing
    # A sidecar beside the link itself would still be read through it: refused.
    (tmp_path / "link.npy.json").write_text('{"spacing": [1, 2, 3]}')
    with pytest.raises(InputError, match="a link to"):
        save_volume(plain, link)
