"""Tokeniser of the expression language and its error type (no ``eval``: numbers, ASCII names and
``+ - * / ^ ** ( ) ,`` are read by hand; anything else is an :class:`ExpressionError` naming it and its column).
"""
from __future__ import annotations

import math
import re
import string
from typing import NamedTuple, Optional

__all__ = ["ExpressionError"]

_NUM = re.compile(r"(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_OPS = ("+", "-", "*", "/", "^", "(", ")", ",")
_HINTS = {"'": "strings are not allowed", '"': "strings are not allowed", ";": "only one expression is allowed",
          "=": "assignment and comparison are not allowed", "[": "indexing and lists are not allowed",
          "{": "braces are not allowed", ":": "':' is not allowed", "@": "'@' is not allowed"}

def _caret(text: str, column: int) -> str:
    i = column - 1
    start, end = max(0, i - 40), min(len(text), i + 40)
    pre, post = ("..." if start > 0 else ""), ("..." if end < len(text) else "")
    shown = "".join(c if c.isprintable() else " " for c in text[start:end])
    return f"  {pre}{shown}{post}\n  {' ' * (len(pre) + i - start)}^"


class ExpressionError(ValueError):
    """A refused expression: ``"{where}: column {c}: {what}"``, then the text and a caret under column c."""

    def __init__(self, what: str, where: str = "<expr>", column: Optional[int] = None, text: Optional[str] = None):
        self.what, self.where, self.column, self.text = what, where, column, text
        msg = f"{where}: column {column}: {what}" if column is not None else f"{where}: {what}"
        if column is not None and text is not None:
            msg += "\n" + _caret(text, column)
        super().__init__(msg)


class _Tok(NamedTuple):
    kind: str          # num | name | op | end | bad (text = the error message)
    text: str
    col: int
    value: float = 0.0


def tokenize(text: str) -> list:
    toks, i, n = [], 0, len(text)
    while i < n:
        c, col = text[i], i + 1
        if c in " \t\r\n":
            i += 1
        elif c in "0123456789" or (c == "." and text[i + 1:i + 2] in tuple("0123456789")):
            s = _NUM.match(text, i).group()
            if not math.isfinite(float(s)):
                return toks + [_Tok("bad", f"number overflows: {s[:30]}", col)]
            toks.append(_Tok("num", s, col, float(s)))
            i += len(s)
        elif c == "_" or c in string.ascii_letters:
            s = _NAME.match(text, i).group()
            toks.append(_Tok("name", s, col))
            i += len(s)
        elif text.startswith("**", i) or c in _OPS:
            op = "**" if text.startswith("**", i) else c
            toks.append(_Tok("op", op, col))
            i += len(op)
        else:
            after = toks and (toks[-1].kind in ("num", "name") or toks[-1].text == ")")
            what = ("attribute access is not allowed" if c == "." and after else
                    f"unexpected character {c!r}" + (f" ({_HINTS[c]})" if c in _HINTS else ""))
            return toks + [_Tok("bad", what, col)]
    return toks + [_Tok("end", "", n + 1)]
