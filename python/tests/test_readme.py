"""The README's Python example runs as written (against the installed package)."""
import os
import re

from conftest import REPO


def test_readme_python_example_runs(capsys):
    text = open(os.path.join(REPO, "README.md")).read()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "README.md has no python example"
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "20 s spiral, closed loop:" in out
