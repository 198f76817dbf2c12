"""Help texts keep their bracketed words: a scenario table such as ``[link]`` or ``[sweep]``
named in a help string is printed as written, not eaten as rich markup."""

import pytest
from typer.testing import CliRunner

from downhole.cli import _load_commands, app


@pytest.mark.parametrize("argv, words", [
    (["sil", "--help"], ["(overrides [link])", "[link] connect_timeout"]),
    (["sweep", "--help"], ["an optional [sweep] table"]),
    (["sil-controller", "--help"], ["[link]"]),
])
def test_help_keeps_bracketed_table_names(argv, words):
    _load_commands()
    out = CliRunner().invoke(app, argv, env={"COLUMNS": "200"}).output
    flat = " ".join(out.split())
    for w in words:
        assert w in flat, (w, out)
