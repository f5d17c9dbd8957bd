"""OpenSCENARIO parameter references (``$name``) and expressions (``${...}``, 1.1+).

The maneuver style writes the declared parameters into the actions they drive, directly
(``$ego_speed_m_s``) or inside an arithmetic expression (``${$ego_s0_m + $dx0_m -
1.35}``), so editing a ParameterDeclaration changes the scenario. This module builds those
strings (``Expressions``: the value for 1.0, which has no expressions) and evaluates them
(``evaluate``) with the subset of the standard's expression grammar we write: numbers,
parameters, ``+ - * /``, unary minus and parentheses.
"""

from __future__ import annotations

import ast
import operator
import re
from collections.abc import Callable, Mapping

#: A parameter reference inside an attribute or an expression.
PARAM_RE = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")

_BINARY: dict[type, Callable[[float, float], float]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
}


class ExpressionError(ValueError):
    """An attribute that does not resolve (undeclared parameter, bad expression)."""


def _eval(node: ast.AST, values: Mapping[str, float]) -> float:
    if isinstance(node, ast.Expression):
        return _eval(node.body, values)
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return float(node.value)
    if isinstance(node, ast.Name):
        if node.id not in values:
            raise ExpressionError(f"undeclared parameter ${node.id}")
        return float(values[node.id])
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        v = _eval(node.operand, values)
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return _BINARY[type(node.op)](_eval(node.left, values), _eval(node.right, values))
    raise ExpressionError(f"unsupported expression element {ast.dump(node)[:40]}")


def evaluate(text: str, values: Mapping[str, str | float]) -> str | float:
    """The value of an attribute: ``$name`` -> the declared value (a string stays a
    string), ``${...}`` -> the arithmetic result (float), anything else unchanged.
    ``ExpressionError`` names an undeclared parameter or an unsupported element."""
    if text.startswith("${") and text.endswith("}"):
        body = PARAM_RE.sub(lambda m: m.group(1), text[2:-1])
        nums: dict[str, float] = {}
        for name in PARAM_RE.findall(text):
            if name not in values:
                raise ExpressionError(f"undeclared parameter ${name} in {text}")
            try:
                nums[name] = float(values[name])
            except ValueError:
                raise ExpressionError(f"${name} is not a number in {text}") from None
        try:
            tree = ast.parse(body, mode="eval")
        except SyntaxError:
            raise ExpressionError(f"not an expression: {text}") from None
        return _eval(tree, nums)
    m = PARAM_RE.fullmatch(text)
    if m:
        if m.group(1) not in values:
            raise ExpressionError(f"undeclared parameter {text}")
        return values[m.group(1)]
    return text


def number(v: float) -> str:
    """A number inside an expression: fixed point, at most 6 decimals, negatives in
    parentheses (``(-1.35)``)."""
    s = f"{round(v, 6):.6f}".rstrip("0").rstrip(".")
    s = "0" if s in ("-0", "") else s
    return f"({s})" if s.startswith("-") else s


class Expressions:
    """Attribute values over the declared parameters of one file: ``ref`` writes a
    reference, ``expr`` an expression (1.1+) or, for OpenSCENARIO 1.0 (no expressions),
    its value rounded to 1e-6."""

    def __init__(self, values: Mapping[str, str | float], minor: int) -> None:
        self.values = dict(values)
        self.minor = minor

    def ref(self, name: str) -> str:
        """``$name`` (the parameter must be declared)."""
        if name not in self.values:
            raise KeyError(f"parameter {name} is not declared")
        return f"${name}"

    def value(self, text: str) -> float:
        """The value of an expression body (``$a + 2 * $b``)."""
        return float(evaluate("${" + text + "}", self.values))

    def expr(self, text: str) -> str | float:
        """``${text}`` (1.1+) or its value (1.0)."""
        v = self.value(text)
        return round(v, 6) if self.minor == 0 else "${" + text + "}"
