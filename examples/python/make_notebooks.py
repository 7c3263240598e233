"""Writes each example script (`# %%` cells, `# %% [markdown]` cells of `# ` comment lines) as
a Jupyter notebook beside it: the scripts are the source, the notebooks are generated, and
`python/tests/test_examples.py` checks that they match. Run: python examples/python/make_notebooks.py"""

import json
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
SCRIPTS = ["quickstart.py", "sigma_s_sweep.py", "mitsuba_compare.py", "smc_anisotropy.py"]


def cells(text: str):
    out = []
    for chunk in text.split("# %%")[1:]:
        head, _, body = chunk.partition("\n")
        lines = body.strip("\n").split("\n")
        if head.strip() == "[markdown]":
            source = [ln[2:] if ln.startswith("# ") else ln.lstrip("#") for ln in lines]
            out.append({"cell_type": "markdown", "metadata": {}, "source": _lines(source)})
        else:
            out.append({"cell_type": "code", "execution_count": None, "metadata": {},
                        "outputs": [], "source": _lines(lines)})
    for i, c in enumerate(out):
        c["id"] = f"cell-{i}"
    return out


def _lines(lines):
    return [ln + "\n" for ln in lines[:-1]] + lines[-1:]


def notebook(script: pathlib.Path) -> str:
    nb = {
        "cells": cells(script.read_text()),
        "metadata": {"kernelspec": {"display_name": "Python 3", "language": "python",
                                    "name": "python3"},
                     "language_info": {"name": "python"}},
        "nbformat": 4,
        "nbformat_minor": 5,
    }
    return json.dumps(nb, indent=1) + "\n"


def main():
    for name in SCRIPTS:
        script = HERE / name
        script.with_suffix(".ipynb").write_text(notebook(script))
    print(f"wrote {len(SCRIPTS)} notebooks", file=sys.stderr)


if __name__ == "__main__":
    main()
