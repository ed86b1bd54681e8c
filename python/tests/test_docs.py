"""docs/python.md's examples run as written: every ```python block, in an empty directory."""
import os
import re
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "python.md"


def blocks():
    text = DOC.read_text(encoding="utf-8")
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def stand_in_matplotlib(monkeypatch):
    """matplotlib when installed, else a stand-in whose plotting calls do nothing."""
    try:
        import matplotlib  # noqa: F401

        matplotlib.use("Agg")
        return
    except ImportError:
        pass
    pyplot = types.ModuleType("matplotlib.pyplot")
    for name in ("plot", "xlabel", "ylabel", "savefig", "figure", "show", "title", "legend"):
        setattr(pyplot, name, lambda *a, **k: None)
    mpl = types.ModuleType("matplotlib")
    mpl.pyplot = pyplot
    monkeypatch.setitem(sys.modules, "matplotlib", mpl)
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", pyplot)


def test_the_page_has_examples():
    assert len(blocks()) >= 3


@pytest.mark.parametrize("k", range(len(blocks())))
def test_python_md_example_runs_as_written(k, tmp_path, monkeypatch, capsys):
    code = blocks()[k]
    stand_in_matplotlib(monkeypatch)
    if "../shared/data/irb120" in code:
        if not (ROOT.parent / "shared" / "data" / "irb120").is_dir():
            pytest.skip("the IRB 120 data (../shared/data/irb120) are not here")
        monkeypatch.chdir(ROOT)
        # Its output file goes to the temporary directory, not into the repository.
        code = code.replace('"irb120_residuals.png"', repr(str(tmp_path / "irb120_residuals.png")))
    else:
        monkeypatch.chdir(tmp_path)
    exec(compile(code, f"docs/python.md block {k + 1}", "exec"), {"__name__": "__main__"})
    out = capsys.readouterr().out
    assert out.strip(), "each example prints its result"
