"""`contactopt examples DIR`: the example configurations and their meshes, shipped with the package,
copied out into a directory a user runs them from."""

from pathlib import Path

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.io.examples import SUFFIXES, copy_examples, list_examples

ROOT = Path(__file__).resolve().parents[1]


def test_every_example_of_the_repository_is_shipped(tmp_path):
    written = {p.relative_to(tmp_path).as_posix() for p in copy_examples(tmp_path)}
    repo = {p.relative_to(ROOT / "examples").as_posix() for p in (ROOT / "examples").rglob("*")
            if p.is_file() and p.suffix in SUFFIXES}
    assert repo and repo <= written
    assert {"example1.toml", "example2.toml", "example3.toml"} <= written


def test_the_copies_load_from_their_new_place(tmp_path):
    copy_examples(tmp_path)
    for ex in list_examples():
        cfg = load_config(tmp_path / ex.files[0])
        mesh = cfg.data.get("body", {}).get("mesh")
        if mesh:                       # resolved against the copied file's directory
            assert Path(mesh).is_file() and Path(mesh).is_relative_to(tmp_path), (ex.name, mesh)
            assert Path(mesh).relative_to(tmp_path).as_posix() in ex.files


def test_command_copies_lists_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "mine"
    assert main(["examples", str(out)]) == 0
    assert "bracket.toml" in capsys.readouterr().out
    (out / "bracket.toml").write_text("# edited\n")
    assert main(["examples", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (out / "bracket.toml").read_text() == "# edited\n"       # nothing touched
    assert main(["examples", str(out), "--overwrite"]) == 0
    assert (out / "bracket.toml").read_text() != "# edited\n"
    assert main(["examples", "--list"]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in ("example1", "bracket", "round_pad", "saddle"))
