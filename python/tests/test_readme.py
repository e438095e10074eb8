"""The README's Python examples run as written and print what their comments say."""

import contextlib
import io
import os
import re

import pytest

README = os.path.join(os.path.dirname(__file__), "..", "..", "README.md")
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e-?\d+)?")


def readme_blocks():
    with open(README, encoding="utf-8") as f:
        text = f.read()
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def expected_prints(code):
    """The numbers each `print(...)  # ...` line's comment promises, in order."""
    return [
        [float(n) for n in NUMBER.findall(line.split("#", 1)[1])]
        for line in code.splitlines()
        if line.startswith("print(") and "#" in line
    ]


def test_the_readme_examples_print_what_they_promise(tmp_path, monkeypatch):
    blocks = readme_blocks()
    assert len(blocks) >= 2, "the README's sparse loop and dense colour map"
    code = "\n".join(blocks)
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), {"__name__": "readme"})
    printed = [[float(n) for n in NUMBER.findall(line)] for line in out.getvalue().splitlines()]
    promised = expected_prints(code)
    assert len(printed) == len(promised)
    for got, want in zip(printed, promised):
        assert got == pytest.approx(want, rel=1e-4, abs=1e-4), (got, want)
    assert (tmp_path / "flow.png").stat().st_size > 0
