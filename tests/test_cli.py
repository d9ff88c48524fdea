"""Command line interface."""

import pytest

from jaxdea import cli


def test_help_lists_the_table_command(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--help"])
    assert exc.value.code == 0
    assert "table" in capsys.readouterr().out


def test_table_help_describes_the_cases(capsys):
    with pytest.raises(SystemExit):
        cli.main(["table", "--help"])
    out = capsys.readouterr().out
    assert "η = 0.85" in out and "--n-layers" in out


def test_rejects_zero_layers(capsys):
    assert cli.main(["table", "--n-layers", "0"]) == 2
    assert "--n-layers must be >= 1" in capsys.readouterr().err
