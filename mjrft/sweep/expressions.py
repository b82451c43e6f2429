"""Arithmetic on a run's parameter values, for the values a study derives from them
(``[set]`` entries written ``{ expr = "..." }``): numbers, parameter names, ``pi``, ``e``,
``tau``, + - * / // % **, and the functions in FUNCTIONS. Nothing else is evaluated."""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Mapping
from typing import Any

from mjrft.sweep.errors import StudyError

CONSTANTS = {"pi": math.pi, "e": math.e, "tau": math.tau}
FUNCTIONS = {
    name: getattr(math, name)
    for name in (
        "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sqrt", "exp", "log", "log10",
        "radians", "degrees", "floor", "ceil", "hypot",
    )
} | {"abs": abs, "min": min, "max": max}  # fmt: skip
_BINARY = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.FloorDiv: operator.floordiv, ast.Mod: operator.mod,
    ast.Pow: operator.pow,
}  # fmt: skip
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}


def parse(expr: str, where: str) -> ast.Expression:
    """The syntax tree of `expr`, or a StudyError naming `where` and the expression."""
    try:
        return ast.parse(expr, mode="eval")
    except SyntaxError as exc:
        raise StudyError(f"{where}: {expr!r} is not an expression ({exc.msg})") from None


def names(expr: str, where: str) -> set[str]:
    """The parameter names `expr` uses (constants and functions excluded)."""
    tree = parse(expr, where)
    used = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    return used - set(CONSTANTS) - set(FUNCTIONS)


def evaluate(expr: str, values: Mapping[str, Any], where: str) -> float:
    """The value of `expr` with the parameter `values` (name -> number)."""
    tree = parse(expr, where)
    try:
        return _eval(tree.body, values, f"{where}: {expr!r}")
    except (ArithmeticError, ValueError, TypeError) as exc:
        if isinstance(exc, StudyError):
            raise
        shown = ", ".join(f"{k} = {v!r}" for k, v in values.items())
        raise StudyError(f"{where}: {expr!r} fails at {shown}: {exc}") from None


def _eval(node: ast.AST, values: Mapping[str, Any], where: str) -> Any:
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return node.value
    if isinstance(node, ast.Name):
        if node.id in values:
            return values[node.id]
        if node.id in CONSTANTS:
            return CONSTANTS[node.id]
        known = ", ".join(sorted(values)) or "none"
        raise StudyError(f"{where}: unknown name {node.id!r} (parameters: {known}; pi, e, tau)")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return _BINARY[type(node.op)](
            _eval(node.left, values, where), _eval(node.right, values, where)
        )
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        return _UNARY[type(node.op)](_eval(node.operand, values, where))
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id in FUNCTIONS
        and not node.keywords
    ):
        return FUNCTIONS[node.func.id](*(_eval(a, values, where) for a in node.args))
    raise StudyError(
        f"{where}: {ast.unparse(node)!r} is not allowed (numbers, parameter names, pi, e, tau, "
        f"+ - * / // % **, and {', '.join(sorted(FUNCTIONS))})"
    )
