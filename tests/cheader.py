"""A small reader of the nx_struct/enum/#define subset of C used in NineDofMsg.h.

It is what lets the host check itself against the one message header: the
test suite compares every ``protocol.MessageSpec`` with what this reads.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

NX_SIZES = {"nx_uint8_t": 1, "nx_int8_t": 1, "nx_uint16_t": 2, "nx_int16_t": 2,
            "nx_uint32_t": 4, "nx_int32_t": 4}


@dataclass
class CField:
    name: str
    ctype: str
    dim: str | None       # array dimension as written (number or name), None for scalars


@dataclass
class CStruct:
    name: str             # struct tag
    typedef: str | None   # typedef name
    fields: list[CField]


@dataclass
class CHeader:
    constants: dict[str, int]
    structs: dict[str, CStruct]     # by tag

    def struct_by_type(self, name: str) -> CStruct:
        for s in self.structs.values():
            if s.typedef == name or s.name == name:
                return s
        raise KeyError(name)

    def dim(self, d: str | None) -> int:
        if d is None:
            return 1
        return int(d, 0) if re.fullmatch(r"(0x)?[0-9a-fA-F]+", d) else self.constants[d]

    def sizeof(self, ctype: str) -> int:
        if ctype in NX_SIZES:
            return NX_SIZES[ctype]
        return sum(self.sizeof(f.ctype) * self.dim(f.dim) for f in self.struct_by_type(ctype).fields)


def _strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    return re.sub(r"//[^\n]*", " ", text)


def _eval(expr: str, consts: dict[str, int]) -> int:
    expr = expr.strip()
    if not re.fullmatch(r"[\w\s+\-*/()<>|&x]+", expr):
        raise ValueError(f"cannot evaluate {expr!r}")
    names = {k: v for k, v in consts.items()}
    return int(eval(expr, {"__builtins__": {}}, names))  # noqa: S307 - restricted charset


def parse_header(path: str | Path) -> CHeader:
    text = _strip_comments(Path(path).read_text())
    consts: dict[str, int] = {}
    for m in re.finditer(r"^\s*#define\s+(\w+)\s+([^\n]+)$", text, flags=re.M):
        try:
            consts[m.group(1)] = _eval(m.group(2), consts)
        except (ValueError, SyntaxError, NameError):
            pass
    for m in re.finditer(r"\benum\s*\{(.*?)\}", text, flags=re.S):
        nxt = 0
        for item in m.group(1).split(","):
            item = item.strip()
            if not item:
                continue
            if "=" in item:
                name, val = item.split("=", 1)
                nxt = _eval(val, consts)
                name = name.strip()
            else:
                name = item
            consts[name] = nxt
            nxt += 1
    structs: dict[str, CStruct] = {}
    for m in re.finditer(r"(typedef\s+)?nx_struct\s+(\w+)\s*\{(.*?)\}\s*(\w*)\s*;", text, flags=re.S):
        tag, body, tdef = m.group(2), m.group(3), m.group(4) or None
        fields: list[CField] = []
        for decl in body.split(";"):
            decl = decl.strip()
            if not decl:
                continue
            dm = re.match(r"(\w+)\s+(.*)$", decl, flags=re.S)
            ctype, names = dm.group(1), dm.group(2)
            for nm in names.split(","):
                nm = nm.strip()
                am = re.fullmatch(r"(\w+)\s*(?:\[\s*(\w+)\s*\])?", nm)
                if not am:
                    raise ValueError(f"cannot parse declaration {decl!r}")
                fields.append(CField(am.group(1), ctype, am.group(2)))
        structs[tag] = CStruct(tag, tdef, fields)
    return CHeader(consts, structs)
