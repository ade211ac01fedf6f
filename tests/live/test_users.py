"""The users file of a live controller (loopworks.live.users) and `loopworks users add`."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from loopworks.errors import FileFormatError, InputError
from loopworks.live.users import add_user, load_users, render


def test_round_trip_keeps_other_users_and_checks_passwords(tmp_path: Path) -> None:
    path = tmp_path / "users.toml"
    assert add_user(path, "alice", "s3cret pass", "operator") is True
    assert add_user(path, "bob.v-2", 'quote" and \\ backslash', "viewer") is True
    users = load_users(path)
    assert len(users) == 2
    assert users.authenticate("alice", "s3cret pass") == "operator"
    assert users.authenticate("bob.v-2", 'quote" and \\ backslash') == "viewer"
    assert users.authenticate("alice", "s3cret pasS") is None  # wrong password
    assert users.authenticate("alice", "") is None
    assert users.authenticate("carol", "s3cret pass") is None  # unknown user
    # updating alice changes her role and password, and keeps bob
    assert add_user(path, "alice", "new one", "viewer") is False
    users = load_users(path)
    assert users.authenticate("alice", "s3cret pass") is None
    assert users.authenticate("alice", "new one") == "viewer"
    assert users.authenticate("bob.v-2", 'quote" and \\ backslash') == "viewer"
    # the file is plain TOML, holds no password, and only its owner can read it
    text = path.read_text()
    assert "s3cret" not in text and "new one" not in text
    data = tomllib.loads(text)
    assert set(data["users"]) == {"alice", "bob.v-2"}  # the dotted name is one quoted key
    entry = data["users"]["alice"]
    assert entry["algorithm"] == "scrypt" and len(bytes.fromhex(entry["salt"])) == 16
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600


def test_salts_differ_so_equal_passwords_hash_differently(tmp_path: Path) -> None:
    path = tmp_path / "users.toml"
    add_user(path, "a", "same", "viewer")
    add_user(path, "b", "same", "viewer")
    users = load_users(path)
    assert users.entries["a"].salt != users.entries["b"].salt
    assert users.entries["a"].hash != users.entries["b"].hash


@pytest.mark.parametrize(("name", "password", "role", "words"), [
    ("alice", "", "operator", ["password", "empty"]),
    ("alice", "x", "admin", ["'admin'", "viewer", "operator"]),
    ("al ice", "x", "viewer", ["'al ice'", "letters, digits"]),
    ("", "x", "viewer", ["''", "letters, digits"]),
    ('a"b', "x", "viewer", ["'a\"b'", "_ . -"]),
])
def test_add_user_refuses_bad_input(tmp_path: Path, name: str, password: str, role: str,
                                    words: list[str]) -> None:
    path = tmp_path / "users.toml"
    with pytest.raises(InputError) as info:
        add_user(path, name, password, role)
    for word in words:
        assert word in str(info.value)
    assert not path.exists()  # nothing written


def _entry(**over: str) -> str:
    fields = {"role": "operator", "algorithm": "scrypt", "salt": "00" * 16, "hash": "11" * 32}
    fields.update(over)
    return "\n".join(f'{k} = "{v}"' for k, v in fields.items())


@pytest.mark.parametrize(("text", "words"), [
    ("[users.alice\nrole = 1", ["invalid TOML"]),
    ("title = 'x'\n", ["unknown key 'title'", "[users.NAME]"]),
    ("users = 3\n", ["'users' is an integer", "[users.NAME]"]),
    ('[users."al ice"]\n' + _entry(), ['[users."al ice"]', "letters, digits"]),
    ("[users]\nalice = 'x'\n", ['[users."alice"]', "a string", "role, algorithm"]),
    ("[users.alice]\n" + _entry(role="admin"), ['[users."alice"]', "role = 'admin'",
                                                 "'viewer', 'operator'"]),
    ("[users.alice]\n" + _entry(algorithm="md5"), ["algorithm = 'md5'", "'scrypt'"]),
    ("[users.alice]\n" + _entry(salt="xyz"), ['[users."alice"]: salt', "hexadecimal"]),
    ("[users.alice]\n" + _entry(hash=""), ['[users."alice"]: hash', "hexadecimal"]),
    ("[users.alice]\nrole = 'viewer'\n", ["missing key 'algorithm'"]),
    ("[users.alice]\n" + _entry() + "\nextra = 'x'", ["unknown key 'extra'"]),
    ("[users.alice]\n" + _entry().replace('role = "operator"', "role = 2"),
     ["role is an integer", "expected a string"]),
])
def test_malformed_files_name_the_file_the_key_and_what_was_expected(
        tmp_path: Path, text: str, words: list[str]) -> None:
    path = tmp_path / "users.toml"
    path.write_text(text)
    with pytest.raises(FileFormatError) as info:
        load_users(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ")
    for word in words:
        assert word in message, message
    # add_user does not overwrite a file it cannot read
    with pytest.raises(FileFormatError):
        add_user(path, "bob", "pw", "viewer")
    assert path.read_text() == text


def test_missing_file_and_empty_file(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match="cannot read the users file"):
        load_users(tmp_path / "nope.toml")
    (tmp_path / "empty.toml").write_text("# nobody yet\n")
    assert len(load_users(tmp_path / "empty.toml")) == 0


def test_render_is_valid_toml_for_every_allowed_name(tmp_path: Path) -> None:
    path = tmp_path / "users.toml"
    names = ["a", "A_b", "x.y.z", "-lead", "9", "dots..", "_"]
    for name in names:
        add_user(path, name, f"pw-{name}", "viewer")
    users = load_users(path)
    assert sorted(users.entries) == sorted(names)
    for name in names:
        assert users.authenticate(name, f"pw-{name}") == "viewer"
    assert tomllib.loads(render(users.entries))["users"].keys() == set(names)


def _cli(*args: str, stdin: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "loopworks", "users", *args], input=stdin,
                          capture_output=True, text=True, timeout=60, check=False)


def test_cli_users_add_reads_the_password_from_stdin(tmp_path: Path) -> None:
    path = tmp_path / "users.toml"
    proc = _cli("add", str(path), "op1", "--role", "operator", stdin="pass word\n")
    assert proc.returncode == 0, proc.stderr
    assert "added user op1 (operator)" in proc.stdout
    proc = _cli("add", str(path), "view", stdin="v\r\n")  # default role: viewer
    assert proc.returncode == 0, proc.stderr
    users = load_users(path)
    assert users.authenticate("op1", "pass word") == "operator"  # inner space kept, \n not
    assert users.authenticate("view", "v") == "viewer"  # \r\n stripped
    proc = _cli("add", str(path), "op1", "--role", "viewer", stdin="other\n")
    assert proc.returncode == 0 and "updated user op1 (viewer)" in proc.stdout
    assert load_users(path).authenticate("op1", "other") == "viewer"


@pytest.mark.parametrize(("args", "stdin", "words"), [
    (["bad name"], "pw\n", ["error: user name 'bad name'", "letters, digits"]),
    (["op", "--role", "admin"], "pw\n", ["error: role 'admin'", "viewer, operator"]),
    (["op"], "\n", ["error: user 'op': the password is empty"]),
    (["op"], "", ["error: user 'op': the password is empty"]),
])
def test_cli_users_add_errors_are_one_line(tmp_path: Path, args: list[str], stdin: str,
                                           words: list[str]) -> None:
    path = tmp_path / "users.toml"
    proc = _cli("add", str(path), *args, stdin=stdin)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    for word in words:
        assert word in proc.stderr
    assert not path.exists()
