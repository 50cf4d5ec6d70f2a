"""repro._cli.run_cli: user and machine errors become one stderr line; bugs propagate."""

import pytest

from repro._cli import run_cli


def _raiser(exc):
    def main(argv=None):
        raise exc
    return main


@pytest.mark.parametrize("exc, needle", [
    (ValueError("x=3 is invalid; allowed: > 4"), "x=3 is invalid"),
    (PermissionError(13, "Permission denied", "/root/out.png"), "Permission denied (/root/out.png)"),
    (OSError(28, "No space left on device"), "No space left on device"),
    (MemoryError(), "out of memory"),
])
def test_user_and_machine_errors_are_one_line_exit_2(exc, needle, capsys):
    assert run_cli(_raiser(exc), [], prog="prog") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("prog: error: ") and needle in err[0]


def test_ctrl_c_is_exit_130(capsys):
    assert run_cli(_raiser(KeyboardInterrupt()), [], prog="prog") == 130
    assert "interrupted" in capsys.readouterr().err


def test_bugs_propagate():
    with pytest.raises(RuntimeError):
        run_cli(_raiser(RuntimeError("bug")), [], prog="prog")


def test_status_passes_through():
    assert run_cli(lambda argv=None: None, []) == 0
    assert run_cli(lambda argv=None: 1, []) == 1
