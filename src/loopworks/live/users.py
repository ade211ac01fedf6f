"""The users file of a live controller: who may read and who may write over OPC UA.

A TOML file, one table per user::

    [users."alice"]
    role = "operator"              # "viewer" reads; "operator" reads and writes
    algorithm = "scrypt"
    salt = "9f0c..."               # 16 random bytes, hex
    hash = "5d2a..."               # hashlib.scrypt(password, salt, n=2**14, r=8, p=1), hex

``add_user`` creates or updates it (``loopworks users add FILE NAME --role operator`` reads the
password from standard input), ``load_users`` reads it and ``Users.authenticate`` checks a
password in constant time. Passwords are never stored; the file is written with mode 0600.
Anonymous clients need no entry: they may read and never write.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import re
import secrets
import tempfile
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from loopworks.errors import FileFormatError, InputError

Role = Literal["viewer", "operator"]
ROLES: tuple[Role, ...] = ("viewer", "operator")
ALGORITHM = "scrypt"
SCRYPT_N = 2**14
SCRYPT_R = 8
SCRYPT_P = 1
SALT_BYTES = 16
HASH_BYTES = 32
NAME_PATTERN = re.compile(r"[A-Za-z0-9_.-]+")
_KEYS = ("role", "algorithm", "salt", "hash")


def hash_password(password: str, salt: bytes, length: int = HASH_BYTES) -> bytes:
    """scrypt (n=2**14, r=8, p=1) of the UTF-8 password: about 45 ms and 16 MiB."""
    return hashlib.scrypt(password.encode("utf-8"), salt=salt, n=SCRYPT_N, r=SCRYPT_R,
                          p=SCRYPT_P, dklen=length)


@dataclass(frozen=True)
class User:
    """One entry of the users file."""

    name: str
    role: Role
    salt: bytes
    hash: bytes
    algorithm: str = ALGORITHM


@dataclass(frozen=True)
class Users:
    """The users of a controller, by name. ``authenticate`` gives a user's role or None."""

    entries: Mapping[str, User] = field(default_factory=dict)
    source: Path | None = None

    def __contains__(self, name: object) -> bool:
        return name in self.entries

    def __len__(self) -> int:
        return len(self.entries)

    def role(self, name: str) -> Role | None:
        """The role of a user, without checking a password (None for an unknown name)."""
        user = self.entries.get(name)
        return None if user is None else user.role

    def authenticate(self, name: str, password: str) -> Role | None:
        """The user's role if the password is right, else None (also for an unknown user,
        which costs the same scrypt so timing does not tell names apart)."""
        user = self.entries.get(name)
        if user is None:
            hash_password(password, b"\0" * SALT_BYTES)
            return None
        given = hash_password(password, user.salt, len(user.hash))
        return user.role if hmac.compare_digest(given, user.hash) else None


def check_name(name: str) -> str:
    """The name if it is a valid user name, else an InputError saying what is allowed."""
    if not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None:
        raise InputError(f"user name {name!r}: allowed are letters, digits and _ . - "
                         f"(at least one character)")
    return name


def check_role(role: str) -> Role:
    """The role if it is one of ROLES, else an InputError listing them."""
    if role == "viewer":
        return "viewer"
    if role == "operator":
        return "operator"
    raise InputError(f"role {role!r}: expected one of {', '.join(ROLES)}")


def load_users(path: str | os.PathLike[str]) -> Users:
    """Read a users file. A malformed one raises FileFormatError naming the file, the key and
    what was expected."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise FileFormatError(f"{path}: cannot read the users file: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{path}: not UTF-8 text (byte {exc.start}): a users file is "
                              f"TOML") from None
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"{path}: invalid TOML: {exc}") from None
    for key in data:
        if key != "users":
            raise FileFormatError(f"{path}: unknown key '{key}': expected only [users.NAME] "
                                  f"tables")
    table = data.get("users", {})
    if not isinstance(table, dict):
        raise FileFormatError(f"{path}: 'users' is {_kind(table)}: expected tables "
                              f"[users.NAME]")
    entries: dict[str, User] = {}
    for name, entry in table.items():
        where = f"{path}: [users.{_toml_key(name)}]"
        if NAME_PATTERN.fullmatch(name) is None:
            raise FileFormatError(f"{where}: invalid user name: allowed are letters, digits "
                                  f"and _ . -")
        if not isinstance(entry, dict):
            raise FileFormatError(f"{where}: is {_kind(entry)}: expected a table with the keys "
                                  f"{', '.join(_KEYS)}")
        for key in entry:
            if key not in _KEYS:
                raise FileFormatError(f"{where}: unknown key '{key}': expected "
                                      f"{', '.join(_KEYS)}")
        for key in _KEYS:
            if key not in entry:
                raise FileFormatError(f"{where}: missing key '{key}'")
            if not isinstance(entry[key], str):
                raise FileFormatError(f"{where}: {key} is {_kind(entry[key])}: expected a "
                                      f"string")
        if entry["role"] not in ROLES:
            raise FileFormatError(f"{where}: role = {entry['role']!r}: expected one of "
                                  f"{', '.join(repr(r) for r in ROLES)}")
        if entry["algorithm"] != ALGORITHM:
            raise FileFormatError(f"{where}: algorithm = {entry['algorithm']!r}: expected "
                                  f"'{ALGORITHM}'")
        salt = _hex(entry["salt"], f"{where}: salt")
        digest = _hex(entry["hash"], f"{where}: hash")
        entries[name] = User(name, entry["role"], salt, digest)
    return Users(entries, path)


def add_user(path: str | os.PathLike[str], name: str, password: str, role: str) -> bool:
    """Create or update the user ``name`` in the users file (created if missing; other users
    are kept). Returns True if the user is new. Refuses an empty password, an unknown role
    and a name outside [A-Za-z0-9_.-] with an InputError."""
    check_name(name)
    checked_role = check_role(role)
    if not isinstance(password, str) or password == "":
        raise InputError(f"user {name!r}: the password is empty: expected at least one "
                         f"character")
    path = Path(path)
    users = load_users(path) if path.exists() else Users({}, path)
    entries = dict(users.entries)
    new = name not in entries
    salt = secrets.token_bytes(SALT_BYTES)
    entries[name] = User(name, checked_role, salt, hash_password(password, salt))
    _write(path, entries)
    return new


def render(entries: Mapping[str, User]) -> str:
    """The TOML text of a users file (written by hand: no TOML writer is a dependency)."""
    lines = ["# loopworks users file: written by `loopworks users add`; roles: viewer (read),",
             "# operator (read and write). Hashes are scrypt (n=2**14, r=8, p=1).", ""]
    for name in sorted(entries):
        user = entries[name]
        lines += [f"[users.{_toml_key(name)}]",
                  f"role = {_toml_string(user.role)}",
                  f"algorithm = {_toml_string(user.algorithm)}",
                  f"salt = {_toml_string(user.salt.hex())}",
                  f"hash = {_toml_string(user.hash.hex())}",
                  ""]
    return "\n".join(lines)


def _write(path: Path, entries: Mapping[str, User]) -> None:
    text = render(entries)
    directory = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=directory)
    except OSError as exc:
        raise FileFormatError(f"{path}: cannot write the users file: {exc.strerror}") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as out:  # mkstemp: mode 0600
            out.write(text)
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise FileFormatError(f"{path}: cannot write the users file: {exc.strerror}") from None


def _toml_string(text: str) -> str:
    """A TOML basic string: backslash, quote and control characters escaped."""
    out = ['"']
    for ch in text:
        code = ord(ch)
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ch == "\r":
            out.append("\\r")
        elif code < 0x20 or code == 0x7F:
            out.append(f"\\u{code:04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_key(name: str) -> str:
    """A key as a quoted TOML key (a bare ``a.b`` would be a nested table)."""
    return _toml_string(name)


def _hex(text: str, what: str) -> bytes:
    try:
        value = bytes.fromhex(text)
    except ValueError:
        value = b""
    if not value:
        raise FileFormatError(f"{what} = {text!r}: expected hexadecimal bytes (an even number "
                              f"of 0-9 a-f digits)")
    return value


def _kind(value: Any) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean",
            int: "an integer", float: "a float"}.get(type(value), type(value).__name__)
