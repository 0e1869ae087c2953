"""JSON text read strictly: the readers' sidecars and parc's transfer-function files."""
from __future__ import annotations

import json


class RepeatedKey(ValueError):
    """A JSON object gave this key twice (`strict_json`)."""


def strict_json(text):
    """`json.loads`, refusing an object that gives a key twice with `RepeatedKey`: JSON keeps the
    last, silently (``{"spacing": [1, 1, 1], "spacing": [4, 4, 4]}`` is read at 4), where TOML
    refuses it, and a file should mean the same in either."""
    def unique(pairs):
        seen = set()
        for key, _ in pairs:
            if key in seen:
                raise RepeatedKey(key)
            seen.add(key)
        return dict(pairs)
    return json.loads(text, object_pairs_hook=unique)
