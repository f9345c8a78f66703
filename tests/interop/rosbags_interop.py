#!/usr/bin/env python3
"""Cross-checks teleop-msgs' CDR bytes against rosbags, an independent implementation.

Driven by shared/msgs/tests/interop_rosbags.rs, which writes into CASE_DIR, for every case:

  <case>.json      {"type": ROS type name, "type_hash": RIHS01 hash, "msg": field values}
  <case>.rust.cdr  the message as encoded by teleop_msgs::encode

For every case this script
  1. deserializes <case>.rust.cdr with rosbags and compares every field with the JSON
     (exactly: floats are compared bit for bit, ints and bools by value and kind),
  2. checks rosbags' own RIHS01 hash of the type against the one in the JSON,
  3. builds the message from the JSON alone and writes rosbags' serialization as
     <case>.py.cdr (little endian) and <case>.py.be.cdr (big endian),
which the Rust test then decodes and compares with its original.

Project types (teleop_msgs/msg/*) are registered from the .msg files in MSG_DIR.

Usage: rosbags_interop.py CASE_DIR MSG_DIR
Exit status 0 when everything matched; 1 with a list of every mismatch otherwise.
"""

from __future__ import annotations

import json
import math
import struct
import sys
from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

BASE = 1
NAME = 2
ARRAY = 3
SEQUENCE = 4

NUMPY_DTYPES = {
    "bool": np.bool_,
    "int8": np.int8,
    "uint8": np.uint8,
    "byte": np.uint8,
    "char": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}

INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "byte": (0, 2**8 - 1),
    "char": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}


def make_typestore():
    # The project targets ROS 2 Kilted; Jazzy's definitions of these types are identical.
    store = getattr(Stores, "ROS2_KILTED", None) or Stores.ROS2_JAZZY
    return store, get_typestore(store)


def register_project_types(typestore, msg_dir: Path) -> list[str]:
    types = {}
    for path in sorted(msg_dir.glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(), f"teleop_msgs/msg/{path.stem}"))
    if not types:
        raise SystemExit(f"no .msg files in {msg_dir}")
    typestore.register(types)
    return sorted(types)


class Checker:
    def __init__(self, typestore):
        self.ts = typestore
        self.errors: list[str] = []

    def fail(self, path: str, text: str) -> None:
        self.errors.append(f"{path}: {text}")

    # ---------------------------------------------------------------- compare

    def compare_message(self, path: str, value, expected: dict, typename: str) -> None:
        _, fields = self.ts.fielddefs[typename]
        names = [name for name, _ in fields]
        if not isinstance(expected, dict):
            self.fail(path, f"JSON is not an object: {expected!r}")
            return
        if sorted(expected) != sorted(names):
            self.fail(path, f"JSON fields {sorted(expected)} != {typename} fields {sorted(names)}")
        for name, desc in fields:
            if name in expected:
                self.compare_field(f"{path}.{name}", getattr(value, name), expected[name], desc)

    def compare_field(self, path: str, value, expected, desc) -> None:
        kind, detail = desc
        if kind == BASE:
            self.compare_base(path, value, expected, detail[0])
        elif kind == NAME:
            self.compare_message(path, value, expected, detail)
        elif kind in (ARRAY, SEQUENCE):
            elem, _bound = detail
            if not isinstance(expected, list):
                self.fail(path, f"JSON is not a list: {expected!r}")
                return
            if len(value) != len(expected):
                self.fail(path, f"length {len(value)} != expected {len(expected)}")
                return
            for i, (v, e) in enumerate(zip(value, expected)):
                self.compare_field(f"{path}[{i}]", v, e, elem)
        else:
            self.fail(path, f"unsupported field kind {kind!r}")

    def compare_base(self, path: str, value, expected, typ: str) -> None:
        if typ in ("float32", "float64"):
            if isinstance(expected, bool) or not isinstance(expected, (int, float)):
                self.fail(path, f"JSON value {expected!r} is not a number")
                return
            fmt = "<d" if typ == "float64" else "<f"
            got = struct.pack(fmt, float(value))
            want = struct.pack(fmt, float(expected))
            if got != want:
                self.fail(path, f"{typ} {float(value)!r} ({got.hex()}) != {float(expected)!r} ({want.hex()})")
        elif typ == "bool":
            if not isinstance(expected, bool) or bool(value) is not expected:
                self.fail(path, f"bool {value!r} != {expected!r}")
        elif typ in INT_RANGES:
            if isinstance(expected, bool) or not isinstance(expected, int):
                self.fail(path, f"JSON value {expected!r} is not an integer")
            elif int(value) != expected:
                self.fail(path, f"{typ} {int(value)} != {expected}")
        elif typ == "string":
            if not isinstance(value, str) or value != expected:
                self.fail(path, f"string {value!r} != {expected!r}")
        else:
            self.fail(path, f"unsupported base type {typ}")

    # ---------------------------------------------------------------- build from JSON

    def build_message(self, path: str, expected: dict, typename: str):
        _, fields = self.ts.fielddefs[typename]
        kwargs = {name: self.build_field(f"{path}.{name}", expected[name], desc) for name, desc in fields}
        return self.ts.types[typename](**kwargs)

    def build_field(self, path: str, expected, desc):
        kind, detail = desc
        if kind == BASE:
            typ = detail[0]
            if typ in ("float32", "float64"):
                value = float(expected)
                if not math.isfinite(value):
                    self.fail(path, "JSON carries a non-finite float")
                return value
            if typ == "bool":
                return bool(expected)
            if typ == "string":
                return str(expected)
            lo, hi = INT_RANGES[typ]
            if not lo <= int(expected) <= hi:
                self.fail(path, f"{expected} out of range for {typ}")
            return int(expected)
        if kind == NAME:
            return self.build_message(path, expected, detail)
        elem, _bound = detail
        ekind, edetail = elem
        if ekind == BASE and edetail[0] in NUMPY_DTYPES:
            return np.array(expected, dtype=NUMPY_DTYPES[edetail[0]])
        return [self.build_field(f"{path}[{i}]", e, elem) for i, e in enumerate(expected)]


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    case_dir = Path(sys.argv[1])
    msg_dir = Path(sys.argv[2])

    from importlib.metadata import version

    store, ts = make_typestore()
    registered = register_project_types(ts, msg_dir)
    print(f"rosbags {version('rosbags')}, typestore {store.name}, registered {', '.join(registered)}")

    checker = Checker(ts)
    cases = sorted(case_dir.glob("*.json"))
    if not cases:
        print(f"FAIL: no cases in {case_dir}", file=sys.stderr)
        return 1
    for case_json in cases:
        case = case_json.stem
        before = len(checker.errors)
        spec = json.loads(case_json.read_text())
        typename = spec["type"]
        if typename not in ts.fielddefs:
            checker.fail(case, f"type {typename} unknown to rosbags")
            continue

        rihs = ts.hash_rihs01(typename)
        if rihs != spec["type_hash"]:
            checker.fail(case, f"type hash: rosbags {rihs} != teleop-msgs {spec['type_hash']}")

        rust_bytes = (case_dir / f"{case}.rust.cdr").read_bytes()
        try:
            decoded = ts.deserialize_cdr(rust_bytes, typename)
        except Exception as exc:  # noqa: BLE001  (report every failure, whatever it is)
            checker.fail(case, f"rosbags cannot deserialize the Rust bytes: {exc!r}")
        else:
            checker.compare_message(case, decoded, spec["msg"], typename)

        try:
            built = checker.build_message(case, spec["msg"], typename)
            le = bytes(ts.serialize_cdr(built, typename))
            be = bytes(ts.serialize_cdr(built, typename, little_endian=False))
        except Exception as exc:  # noqa: BLE001
            checker.fail(case, f"rosbags cannot serialize the JSON message: {exc!r}")
        else:
            (case_dir / f"{case}.py.cdr").write_bytes(le)
            (case_dir / f"{case}.py.be.cdr").write_bytes(be)
            if le != rust_bytes:
                checker.fail(case, f"rosbags bytes differ from Rust bytes:\n  py   {le.hex()}\n  rust {rust_bytes.hex()}")

        status = "ok" if len(checker.errors) == before else "MISMATCH"
        print(f"{case:32} {typename:38} {len(rust_bytes):7} bytes  {status}")

    if checker.errors:
        print(f"\nFAIL: {len(checker.errors)} mismatch(es) between teleop-msgs and rosbags:", file=sys.stderr)
        for e in checker.errors:
            print(f"  {e}", file=sys.stderr)
        return 1
    print(f"rosbags interop: all {len(cases)} cases match")
    return 0


if __name__ == "__main__":
    sys.exit(main())
