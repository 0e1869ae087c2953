"""The readers' tests' check of a refused file: one InputError line that names the file."""
import pytest

from data_tools import InputError
from data_tools.io import load_volume


def fails(path, match=None, **options):
    """Load ``path`` expecting InputError; the message is one line that names the file (and holds
    ``match``, case aside); returned for further checks."""
    with pytest.raises(InputError) as info:
        load_volume(path, **options)
    msg = str(info.value)
    assert "\n" not in msg
    assert str(path) in msg
    if match:
        assert match.lower() in msg.lower(), msg
    return msg
