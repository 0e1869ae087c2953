"""Hand-made `parc.compare` rows and the report's tables read back, for the bench tests."""


def compare_row(method, seconds, phases=None, **kw):
    """A `parc.compare` row as the bench sections read it."""
    row = {"method": method, "seconds": seconds, "phases": phases or {}, "cells_visited": 0, "cubic_solves": 0,
           "samples": 0, "pixels": 64, "polygons": 0, "supercell": None, "hits": 0, "speedup": 1.0,
           "hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0, "psnr": float("inf")}
    return {**row, **kw}


def table_cells(md, heading):
    """The first table after ``heading`` in ``md`` (a list of report lines), as dicts of its cells."""
    after = md[next(i for i, part in enumerate(md) if part.startswith(heading)):]
    lines = next(part for part in after if part.startswith("| ")).splitlines()
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    return [dict(zip(head, (c.strip() for c in line.strip("|").split("|")))) for line in lines[2:]]
