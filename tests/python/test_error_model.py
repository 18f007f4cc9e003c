"""The package's one error model (``uwhl_rs.errors``): every exception it
defines is a ``uwhl_rs.UwhlError`` with the exit-code name of docs/CLI.md
as its ``kind``, keeps its builtin base, and ``uwhl``'s one ``main`` turns
any exception into one error line and its exit code."""

from __future__ import annotations

import importlib
import json
import os
import pkgutil

import pytest

import uwhl_rs
from uwhl_rs import _core, errors
from uwhl_rs.cli import main

EXIT = {name: code for code, name, _ in _core.EXIT_CODES}


def _package_exceptions() -> list[type]:
    found = set()
    for m in pkgutil.walk_packages(uwhl_rs.__path__, "uwhl_rs."):
        mod = importlib.import_module(m.name)
        for v in vars(mod).values():
            if isinstance(v, type) and issubclass(v, BaseException) and v.__module__.startswith("uwhl_rs.") \
                    and v.__module__ != "uwhl_rs._core":
                found.add(v)
    return sorted(found, key=lambda c: (c.__module__, c.__name__))


def test_every_exception_of_the_package_is_a_uwhl_error_with_a_kind():
    classes = _package_exceptions()
    assert {c.__name__ for c in classes} >= {"ImageReadError", "ImageTooLargeError", "BatchError", "IfdoError",
                                             "ManifestError", "CommandError"}
    for c in classes:
        assert issubclass(c, uwhl_rs.UwhlError), c
        assert c.kind in EXIT, (c, c.kind)


def test_builtin_bases_are_kept():
    # `except ValueError` around reading, the iFDO header or a manifest keeps working
    for c in (uwhl_rs.ImageReadError, uwhl_rs.ImageTooLargeError, uwhl_rs.IfdoError, uwhl_rs.ManifestError):
        assert issubclass(c, ValueError), c
    assert issubclass(uwhl_rs.ImageTooLargeError, uwhl_rs.ImageReadError)


@pytest.mark.parametrize("e, writing, kind", [
    (uwhl_rs.ImageReadError("x: empty file"), False, "unreadable_input"),
    (uwhl_rs.ImageTooLargeError("x: 9x9 pixels is over the limit"), False, "over_budget"),
    (uwhl_rs.BatchError("cannot reach the storage"), False, "unreachable"),
    (uwhl_rs.BatchError("fsspec is not installed", "bad_arguments"), False, "bad_arguments"),
    (uwhl_rs.IfdoError("image-pi is missing"), False, "bad_arguments"),
    (uwhl_rs.ManifestError("images[0]: no path"), False, "unreadable_input"),
    (uwhl_rs.ImageError("image has dtype int8"), False, "unreadable_input"),
    (uwhl_rs.ParameterError("guided_eps must be > 0"), False, "bad_arguments"),
    (MemoryError("needs 9 GB"), True, "over_budget"),
    (OSError(28, "No space left on device"), True, "write_failed"),
    (FileNotFoundError(2, "No such file or directory"), False, "unreadable_input"),
    (RuntimeError("a bug"), False, "internal"),
])
def test_kind_of_reads_the_kind_where_it_was_set(e, writing, kind):
    assert errors.kind_of(e, writing) == kind


def test_the_core_raises_its_errors_with_their_kind():
    import numpy as np

    img = np.full((16, 16, 3), 0.3, np.float32)
    with pytest.raises(uwhl_rs.ImageError) as constant:
        uwhl_rs.restore(img)
    with pytest.raises(uwhl_rs.ParameterError) as bad_eps:
        uwhl_rs.restore(img, guided_eps=-1.0)
    with pytest.raises(uwhl_rs.ParameterError) as bad_format:
        _core.output_suffixes("gif")
    assert (constant.value.kind, bad_eps.value.kind, bad_format.value.kind) == \
        ("unreadable_input", "bad_arguments", "bad_arguments")
    assert "gif" in str(bad_format.value)


def test_output_names_are_the_files_layers():
    from uwhl_rs import files

    # docs/OUTPUTS.md: NAME.tif, NAME_t.png, NAME_t_color.png, NAME_confidence.png, NAME_sheet.png, then NAME.json
    assert files.output_suffixes("tiff", True) == [".tif", "_t.png", "_t_color.png", "_confidence.png", "_sheet.png"]
    assert files.output_suffixes() == [".jpg", "_t.png", "_t_color.png", "_confidence.png"]
    with pytest.raises(ValueError):
        files.output_suffixes("gif")


def test_a_kind_set_on_an_error_wins_over_its_class():
    e = uwhl_rs.ImageError("too large to decode")
    e.kind = "over_budget"
    assert errors.kind_of(e) == "over_budget"
    with pytest.raises(ValueError, match="unknown error kind"):
        errors.CommandError("x", "no_such_kind")


def test_main_turns_any_exception_into_one_line_and_its_code(monkeypatch, capsys, tmp_path):
    from uwhl_rs.cli import report as report_command

    def broken(out_dir, console, storage_options=None):
        raise RuntimeError("a bug in the report")

    monkeypatch.setattr(report_command, "write", broken)
    assert main(["report", str(tmp_path)]) == EXIT["internal"]
    got = capsys.readouterr()
    assert got.out == "" and got.err == "uwhl: RuntimeError: a bug in the report\n"
    assert main(["report", str(tmp_path), "--json-errors"]) == EXIT["internal"]
    obj = json.loads(capsys.readouterr().err)
    assert obj == {"error": "internal", "input": None, "message": "RuntimeError: a bug in the report",
                   "exit_code": EXIT["internal"]}


def test_a_command_error_names_its_folder_and_kind(capsys, tmp_path):
    missing = os.path.join(str(tmp_path), "nowhere")
    assert main(["report", missing]) == EXIT["unreadable_input"]
    assert capsys.readouterr().err == f"uwhl: {missing}: no such folder\n"
    assert main(["report", str(tmp_path), "--storage-option", "nokey"]) == EXIT["bad_arguments"]
    assert "is not KEY=VALUE" in capsys.readouterr().err
