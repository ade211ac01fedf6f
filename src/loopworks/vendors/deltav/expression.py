r"""The subset of the DeltaV expression language that a CALC block needs (spec vendor-blocks 6.1).

Three steps, each readable on its own:

1. :func:`tokenize`: the text into tokens (comments dropped), each with its line and column;
2. :func:`parse`: the tokens into statements and expressions (an AST), checked for syntax;
3. :func:`compile_program`: the AST into a flat list of floats, a program for a small stack
   machine, which the ``deltav.calc`` kernel runs once per scan (numba compiles it like any
   other kernel).

Syntax accepted (spec 6.1 [V], DeltaV Books Online "Syntax rules" and "Operators" [R49])::

    program    := { statement } , separated by ';' (a ';' before ELSE, ELSIF, END_IF or the
                  end of the text may be left out, as the seed does on lines 6, 12, 23, 26)
    statement  := reference ':=' expr
                | IF expr THEN statements { ELSIF expr THEN statements }
                  [ ELSE statements ] ( END_IF | ENDIF )
    reference  := '^/NAME'  |  '^/NAME.CV'  |  '^/NAME.ST'       (quoted, as in DeltaV)
    comment    := (* any text, over several lines *)

Operators, from the tightest binding to the loosest (left to right within a level)::

    - (negation), + (unary), NOT, !
    *  /
    +  -
    <  >  <=  >=
    =  !=  <>  ~=  |=        (|= is the seed palette's OCR rendering of != , spec 6.1)
    AND
    OR

Numbers are decimal literals (``0.5``, ``.5``, ``2``, ``3.4e38``; one beyond the float64 range,
``1e999``, is an error); ``TRUE`` and ``FALSE`` are 1 and 0. Keywords may be written in any
letter case; parameter names too (``'^/pv'`` is PV).

Values (spec 6.1): every value is a float. A comparison gives 1 or 0; AND, OR and NOT take any
non-zero value as true and give 1 or 0 (DeltaV "Operators" page: "the logical AND operator
produces the value 1 if both operands are 1 (non-zero)"), and an IF takes any non-zero
condition as true. NaN follows IEEE 754: arithmetic propagates it, ``= < > <= >=`` are false,
``!=`` is true (it is NOT ``=``), and NaN counts as non-zero, so as true, in AND, OR, NOT and IF
(the C rule ``x != 0``). That is within a statement: a result that is not finite is never
stored (the assigned parameter holds its value, Bad; ``deltav.calc``, "Non-finite values").

Division by zero (DeltaV "Operators" page, under ``/``): a first operand < 0 gives
-3.402823466e+38 and a first operand >= 0 gives +3.402823466e+38 (the float32 maximum); NaN
divided by zero stays NaN [A]. ``divide_by_zero="ieee"`` gives IEEE 754 instead (±inf, and NaN
for 0/0).

What this subset does not take, with the error it gives: module-relative ``'/...'`` and external
``'//...'`` paths, fields other than CV and ST (``.CST``, ``.AWST``), unquoted names (IN1,
OUT1, temporary variables, named states), functions, and the operators ``**``, ``MOD``,
``XOR``, ``?:``, and the bitwise ``& | ^ ~ %``.

Errors are :class:`ExpressionError` (a :class:`~loopworks.errors.ParameterError`) whose message
names the line and column and what was expected, e.g.
``expression, line 15, column 23: expected ')' but found ';'``. Whatever the text, the parser
gives a program or such an error, never another exception (a fuzz test pins it): parentheses,
unary operators and IFs nested more than 32 deep, and a program needing a value stack deeper
than 64, are refused as "nested too deeply"; a long chain of operators (``1 + 1 + ... + 1``) is
compiled without recursion, at any length.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from loopworks.errors import ParameterError

# -- opcodes of the compiled program: pairs (opcode, argument) ---------------------------------
OP_CONST = 1  # push the argument
OP_INPUT = 2  # push input value u[arg]
OP_INPUT_ST = 3  # push input status us[arg]
OP_LOAD = 4  # push the value of written parameter arg
OP_LOAD_ST = 5  # push the status of written parameter arg
OP_STORE = 6  # pop into the value of written parameter arg
OP_STORE_ST = 7  # pop into the status of written parameter arg
OP_NEG = 8
OP_NOT = 9
OP_ADD = 10
OP_SUB = 11
OP_MUL = 12
OP_DIV = 13
OP_EQ = 14
OP_NE = 15
OP_LT = 16
OP_GT = 17
OP_LE = 18
OP_GE = 19
OP_AND = 20
OP_OR = 21
OP_JUMP = 22  # continue at code index arg
OP_JUMP_IF_FALSE = 23  # pop; if it is 0, continue at code index arg

MAX_STACK = 64
"""Deepest value stack a program may need (far beyond the seed's 5)."""
MAX_NESTING = 32
"""Deepest nesting of parentheses, unary operators and IF statements (the seed nests 3)."""

SEED_EXPRESSION = """\
(* COMPUTE DITHER AND KICK AMPLITUDES *)
'^/DITHER_AMP' := ('^/RESOLUTION' + 0.5*'^/DEADBAND')*'^/DITHER_FACTOR'*0.5;
'^/KICKER_OUT' := ('^/RESOLUTION' + 0.5*'^/DEADBAND')*'^/KICKER_FACTOR'*0.5;
(* NOISE BAND *)
IF ('^/INITIALIZE' = 1 AND '^/KICK_START' = 1 ) THEN
'^/NOISE_BAND' := 0.0
ELSE
'^/NOISE_BAND' := '^/DITHER_AMP'*'^/PROCESS_GAIN'*'^/NOISE_FACTOR';
ENDIF;
(* IF LOOP IS IN MANUAL, PASS THROUGH PID OUTPUT WITHOUT COMPENSATION *)
IF ('^/COMP_START' = 0) THEN
'^/SIGNAL_OUT' := '^/SIGNAL_IN'
ELSE
(* IF OUTSIDE NOISE BAND, KICK THE PV BACK TOWARDS THE SP DITHER OTHERWISE THE OUTPUT *)
  IF ('^/PV' > ('^/SP' + '^/NOISE_BAND'*0.5)) THEN
    '^/KICKER_DELT' := '^/KICKER_OUT'*'^/CNTRL_ACTION'*'^/VALVE_ACTION';
    '^/DITHER_DELT' := 0.0;
  ELSE
    IF ('^/PV' < ('^/SP' - '^/NOISE_BAND')) THEN
      '^/KICKER_DELT' := - '^/KICKER_OUT'*'^/CNTRL_ACTION'*'^/VALVE_ACTION';
      '^/DITHER_DELT' := 0.0;
    ELSE
      '^/DITHER_DELT' := '^/DITHER_OUT'*'^/CNTRL_ACTION'*'^/VALVE_ACTION'
    ENDIF;
  ENDIF;
'^/SIGNAL_OUT' := '^/SIGNAL_IN' + '^/KICKER_DELT' + '^/DITHER_DELT'
ENDIF;
'^/SIGNAL_OUT.ST' := '^/SIGNAL_IN.ST';
"""
"""The compensator expression of seed 000, exactly as printed (line numbers removed), so a
line/column in an error message is the seed's line number."""


class ExpressionError(ParameterError):
    """A syntax error or a bad reference in a CALC expression, at a line and column."""

    def __init__(self, line: int, column: int, message: str, where: str = "") -> None:
        prefix = f"{where}: " if where else ""
        super().__init__(f"{prefix}expression, line {line}, column {column}: {message}")
        self.line = line
        self.column = column
        self.detail = message


# -- 1. tokens -----------------------------------------------------------------------------------

KEYWORDS = frozenset({"IF", "THEN", "ELSE", "ELSIF", "END_IF", "ENDIF", "AND", "OR", "NOT",
                      "TRUE", "FALSE"})
_UNSUPPORTED_WORDS = frozenset({"MOD", "XOR"})
# longest first, so that ':=' wins over ':' and '<=' over '<'
_OPERATORS = (":=", "<=", ">=", "!=", "<>", "~=", "|=", "**",
              "+", "-", "*", "/", "(", ")", "<", ">", "=", ";", "!")
_UNSUPPORTED_CHARS = {"?": "the conditional operator '? :'", ":": "the conditional operator '? :'",
                      "&": "the bitwise operator '&'", "|": "the bitwise operator '|'",
                      "^": "the bitwise operator '^'", "~": "the bitwise operator '~'",
                      "%": "the modulus operator '%'"}
_NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_FIELDS = ("CV", "ST")


@dataclass(frozen=True)
class Token:
    """One token: ``kind`` is "number", "ref", "word" (a keyword, upper case), "op" or "end"."""

    kind: str
    text: str
    line: int
    column: int

    def show(self) -> str:
        """The token as an error message quotes it."""
        if self.kind == "end":
            return "the end of the expression"
        if self.kind == "ref":
            return self.text
        return f"'{self.text}'"


def tokenize(text: str) -> list[Token]:
    """The tokens of ``text``, ending with an "end" token. Comments ``(* *)`` are dropped."""
    tokens: list[Token] = []
    i, line, line_start, n = 0, 1, 0, len(text)

    def where(pos: int) -> tuple[int, int]:
        return line, pos - line_start + 1

    while i < n:
        c = text[i]
        if c == "\n":
            i += 1
            line, line_start = line + 1, i
            continue
        if c in " \t\r\f\v":
            i += 1
            continue
        if text.startswith("(*", i):  # a comment, possibly over several lines
            start = where(i)
            end = text.find("*)", i + 2)
            if end < 0:
                raise ExpressionError(*start, "the comment '(*' is never closed: expected '*)'")
            for j in range(i, end):
                if text[j] == "\n":
                    line, line_start = line + 1, j + 1
            i = end + 2
            continue
        ln, col = where(i)
        if c == "'":
            end = text.find("'", i + 1)
            newline = text.find("\n", i + 1)
            if end < 0 or 0 <= newline < end:
                raise ExpressionError(ln, col, "the quoted reference is never closed: "
                                               "expected \"'\" before the end of the line")
            tokens.append(Token("ref", text[i:end + 1], ln, col))
            i = end + 1
            continue
        m = _NUMBER.match(text, i)
        if m:
            after = m.end()
            if after < n and (text[after].isalnum() or text[after] in "_."):
                raise ExpressionError(ln, col, f"malformed number "
                                               f"'{text[i:after + 1]}'")
            if not math.isfinite(float(m.group())):
                raise ExpressionError(ln, col, f"number '{m.group()}' is out of range: a "
                                               "literal must be a finite float64 (below 1.8e308)")
            tokens.append(Token("number", m.group(), ln, col))
            i = after
            continue
        m = _WORD.match(text, i)
        if m:
            word = m.group().upper()
            if word in KEYWORDS:
                tokens.append(Token("word", word, ln, col))
            elif word in _UNSUPPORTED_WORDS:
                raise ExpressionError(ln, col, f"the operator '{word}' is not supported by "
                                               "this CALC subset")
            else:
                raise ExpressionError(
                    ln, col, f"unquoted name '{m.group()}': this CALC subset reads and writes "
                             "module parameters only, written in quotes as '^/NAME'")
            i = m.end()
            continue
        for op in _OPERATORS:
            if text.startswith(op, i):
                if op == "**":
                    raise ExpressionError(ln, col, "the power operator '**' is not supported "
                                                   "by this CALC subset")
                tokens.append(Token("op", op, ln, col))
                i += len(op)
                break
        else:
            what = _UNSUPPORTED_CHARS.get(c)
            if what:
                raise ExpressionError(ln, col, f"{what} is not supported by this CALC subset")
            raise ExpressionError(ln, col, f"unexpected character {c!r}")
    tokens.append(Token("end", "", *where(n)))
    return tokens


# -- 2. the syntax tree --------------------------------------------------------------------------


@dataclass(frozen=True)
class Num:
    """A numeric literal."""

    value: float
    line: int
    column: int


@dataclass(frozen=True)
class Ref:
    """A module parameter reference ``'^/NAME'`` (field "cv") or ``'^/NAME.ST'`` (field "st").
    ``name`` is lower case (the block's port and parameter name)."""

    name: str
    field: str
    text: str
    line: int
    column: int


@dataclass(frozen=True)
class Unary:
    """``-x``, ``+x`` or ``NOT x`` (op "-", "+", "NOT")."""

    op: str
    operand: Expr
    line: int
    column: int


@dataclass(frozen=True)
class Binary:
    """``left op right``; op is one of + - * / = != < > <= >= AND OR (not-equal spellings are
    all stored as "!=")."""

    op: str
    left: Expr
    right: Expr
    line: int
    column: int


Expr = Num | Ref | Unary | Binary


@dataclass(frozen=True)
class Assign:
    """``target := value``."""

    target: Ref
    value: Expr
    line: int
    column: int


@dataclass(frozen=True)
class If:
    """``IF c1 THEN s1 ELSIF c2 THEN s2 ... ELSE s_else END_IF``."""

    branches: tuple[tuple[Expr, tuple[Statement, ...]], ...]
    orelse: tuple[Statement, ...]
    line: int
    column: int


Statement = Assign | If


@dataclass
class Program:
    """A parsed expression: its statements and the module parameters it references.

    ``names`` lists every referenced name in order of first appearance; ``written`` the names
    assigned anywhere (value or .ST), ``read_refs`` the first read reference of each name read
    (for error positions), and ``status_read`` / ``status_written`` the names whose .ST field is
    read / assigned."""

    statements: tuple[Statement, ...]
    names: list[str] = field(default_factory=list)
    written: list[str] = field(default_factory=list)
    read_refs: dict[str, Ref] = field(default_factory=dict)
    first_refs: dict[str, Ref] = field(default_factory=dict)
    status_read: set[str] = field(default_factory=set)
    status_written: set[str] = field(default_factory=set)

    @property
    def read_only(self) -> list[str]:
        """Names the expression reads but never assigns: the block's inputs."""
        return [n for n in self.names if n not in self.written]


_EQUALITY = {"=": "=", "!=": "!=", "<>": "!=", "~=": "!=", "|=": "!="}
_RELATIONAL = ("<", ">", "<=", ">=")


class _Parser:
    """Recursive descent over the token list (grammar in the module docstring)."""

    def __init__(self, tokens: list[Token]) -> None:
        self.tokens = tokens
        self.i = 0
        self.depth = 0  # nesting of parentheses, unary operators and IFs

    def enter(self, tok: Token) -> None:
        """One level deeper (each level is a few Python frames): refuse more than
        MAX_NESTING."""
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise ExpressionError(tok.line, tok.column, f"the expression is nested too deeply "
                                  f"(more than {MAX_NESTING} levels of parentheses, unary "
                                  "operators and IFs)")

    def peek(self) -> Token:
        return self.tokens[self.i]

    def advance(self) -> Token:
        tok = self.tokens[self.i]
        if tok.kind != "end":
            self.i += 1
        return tok

    def is_op(self, *ops: str) -> bool:
        tok = self.peek()
        return tok.kind == "op" and tok.text in ops

    def is_word(self, *words: str) -> bool:
        tok = self.peek()
        return tok.kind == "word" and tok.text in words

    def fail(self, expected: str) -> ExpressionError:
        tok = self.peek()
        return ExpressionError(tok.line, tok.column, f"expected {expected} but found {tok.show()}")

    def expect_op(self, op: str) -> Token:
        if not self.is_op(op):
            raise self.fail(f"'{op}'")
        return self.advance()

    # statements
    def program(self) -> tuple[Statement, ...]:
        body = self.statements(())
        if self.peek().kind != "end":
            raise self.fail("a statement (an assignment to '^/NAME' or an IF)")
        return body

    def statements(self, stops: tuple[str, ...]) -> tuple[Statement, ...]:
        """Statements up to one of the keywords ``stops`` (or the end of the text)."""
        body: list[Statement] = []
        while True:
            if self.is_op(";"):
                self.advance()
                continue
            if self.peek().kind == "end" or self.is_word(*stops):
                return tuple(body)
            body.append(self.statement())
            if self.is_op(";"):
                self.advance()
            elif not (self.peek().kind == "end" or self.is_word(*stops)):
                raise self.fail("';'")

    def statement(self) -> Statement:
        tok = self.peek()
        if tok.kind == "ref":
            target = self.reference(self.advance())
            if self.is_op("=") or not self.is_op(":="):
                raise self.fail("':='")
            self.advance()
            return Assign(target, self.expr(), tok.line, tok.column)
        if self.is_word("IF"):
            return self.if_statement()
        raise self.fail("a statement (an assignment to '^/NAME' or an IF)")

    def if_statement(self) -> If:
        start = self.advance()
        self.enter(start)
        branches: list[tuple[Expr, tuple[Statement, ...]]] = []
        orelse: tuple[Statement, ...] = ()
        while True:
            cond = self.expr()
            if not self.is_word("THEN"):
                raise self.fail("'THEN'")
            self.advance()
            body = self.statements(("ELSIF", "ELSE", "END_IF", "ENDIF"))
            branches.append((cond, body))
            if self.is_word("ELSIF"):
                self.advance()
                continue
            if self.is_word("ELSE"):
                self.advance()
                orelse = self.statements(("END_IF", "ENDIF"))
            if not self.is_word("END_IF", "ENDIF"):
                raise self.fail(f"'END_IF' (or 'ENDIF') to close the IF of line {start.line}")
            self.advance()
            self.depth -= 1
            return If(tuple(branches), orelse, start.line, start.column)

    # expressions, loosest first
    def expr(self) -> Expr:
        left = self.conjunction()
        while self.is_word("OR"):
            tok = self.advance()
            left = Binary("OR", left, self.conjunction(), tok.line, tok.column)
        return left

    def conjunction(self) -> Expr:
        left = self.equality()
        while self.is_word("AND"):
            tok = self.advance()
            left = Binary("AND", left, self.equality(), tok.line, tok.column)
        return left

    def equality(self) -> Expr:
        left = self.relation()
        while self.is_op(*_EQUALITY):
            tok = self.advance()
            left = Binary(_EQUALITY[tok.text], left, self.relation(), tok.line, tok.column)
        return left

    def relation(self) -> Expr:
        left = self.sum()
        while self.is_op(*_RELATIONAL):
            tok = self.advance()
            left = Binary(tok.text, left, self.sum(), tok.line, tok.column)
        return left

    def sum(self) -> Expr:
        left = self.product()
        while self.is_op("+", "-"):
            tok = self.advance()
            left = Binary(tok.text, left, self.product(), tok.line, tok.column)
        return left

    def product(self) -> Expr:
        left = self.unary()
        while self.is_op("*", "/"):
            tok = self.advance()
            left = Binary(tok.text, left, self.unary(), tok.line, tok.column)
        return left

    def unary(self) -> Expr:
        tok = self.peek()
        if self.is_op("-", "+", "!") or self.is_word("NOT"):
            self.advance()
            self.enter(tok)
            op = "NOT" if tok.text in ("!", "NOT") else tok.text
            operand = self.unary()
            self.depth -= 1
            return Unary(op, operand, tok.line, tok.column)
        return self.primary()

    def primary(self) -> Expr:
        tok = self.peek()
        if tok.kind == "number":
            self.advance()
            return Num(float(tok.text), tok.line, tok.column)
        if tok.kind == "ref":
            return self.reference(self.advance())
        if self.is_word("TRUE", "FALSE"):
            self.advance()
            return Num(1.0 if tok.text == "TRUE" else 0.0, tok.line, tok.column)
        if self.is_op("("):
            self.enter(self.advance())
            inner = self.expr()
            self.expect_op(")")
            self.depth -= 1
            return inner
        raise self.fail("an operand (a number, a '^/NAME' reference or '(')")

    def reference(self, tok: Token) -> Ref:
        """Check a quoted path: only ``'^/NAME'`` with an optional .CV or .ST field."""
        path = tok.text[1:-1].strip()
        if path.startswith("//"):
            raise ExpressionError(tok.line, tok.column, f"external reference {tok.text} is not "
                                  "supported: this block reads module parameters, '^/NAME'")
        if path.startswith("/"):
            raise ExpressionError(tok.line, tok.column, f"module-relative reference {tok.text} "
                                  "is not supported: this block reads module parameters "
                                  "through '^/NAME'")
        if not path.startswith("^/"):
            raise ExpressionError(tok.line, tok.column, f"expected a reference of the form "
                                  f"'^/NAME' or '^/NAME.ST' but found {tok.text}")
        name, dot, fld = path[2:].partition(".")
        if not _NAME.match(name):
            raise ExpressionError(tok.line, tok.column, f"{tok.text}: expected a parameter name "
                                  "(letters, digits and '_') after '^/'")
        fld = fld.upper() if dot else "CV"
        if fld not in _FIELDS:
            raise ExpressionError(tok.line, tok.column, f"{tok.text}: field '.{fld}' is not "
                                  "supported: expected .CV (the value, the default) or .ST")
        return Ref(name.lower(), fld.lower(), tok.text, tok.line, tok.column)


def parse(text: str) -> Program:
    """Parse an expression text into a :class:`Program`; raise :class:`ExpressionError`."""
    statements = _Parser(tokenize(text)).program()
    prog = Program(statements)
    _collect(prog, statements)
    return prog


def _collect(prog: Program, statements: tuple[Statement, ...]) -> None:
    """Record the references in text order: names, assigned names, reads and .ST use."""

    def note(ref: Ref) -> None:
        if ref.name not in prog.first_refs:
            prog.first_refs[ref.name] = ref
            prog.names.append(ref.name)

    def read(e: Expr) -> None:
        spine = _left_spine(e)  # a long chain a + b + c ... without deep recursion
        e = spine[-1].left if spine else e
        if isinstance(e, Ref):
            note(e)
            prog.read_refs.setdefault(e.name, e)
            if e.field == "st":
                prog.status_read.add(e.name)
        elif isinstance(e, Unary):
            read(e.operand)
        for b in reversed(spine):
            read(b.right)

    def walk(body: tuple[Statement, ...]) -> None:
        for s in body:
            if isinstance(s, Assign):
                note(s.target)
                read(s.value)
                if s.target.name not in prog.written:
                    prog.written.append(s.target.name)
                if s.target.field == "st":
                    prog.status_written.add(s.target.name)
            else:
                for cond, branch in s.branches:
                    read(cond)
                    walk(branch)
                walk(s.orelse)

    walk(statements)


def _left_spine(e: Expr) -> list[Binary]:
    """The binary operators down the left side of ``e``, outermost first: a chain
    ``a + b + c`` parses as ``(a + b) + c``, as deep as it is long, so walking it by recursion
    would overflow Python's stack for a long chain."""
    spine: list[Binary] = []
    while isinstance(e, Binary):
        spine.append(e)
        e = e.left
    return spine


# -- 3. the flat program -------------------------------------------------------------------------

_BINARY_OPS = {"+": OP_ADD, "-": OP_SUB, "*": OP_MUL, "/": OP_DIV, "=": OP_EQ, "!=": OP_NE,
               "<": OP_LT, ">": OP_GT, "<=": OP_LE, ">=": OP_GE, "AND": OP_AND, "OR": OP_OR}


@dataclass
class Compiled:
    """A program for the stack machine: ``code`` is pairs (opcode, argument) as floats, jump
    arguments are indices into ``code``; ``stack`` is the deepest stack it needs."""

    code: list[float]
    stack: int


def compile_program(prog: Program, inputs: dict[str, int], outputs: dict[str, int]) -> Compiled:
    """Compile ``prog``. ``inputs`` maps read-only names to input slots (u, us), ``outputs``
    maps assigned names to written-parameter slots. Statements run top to bottom; an IF
    evaluates its condition, jumps past its branch when the condition is 0, and jumps to its
    end after a branch."""
    code: list[float] = []
    depth = 0
    deepest = 0

    def emit(op: int, arg: float = 0.0, push: int = 0) -> int:
        nonlocal depth, deepest
        code.extend((float(op), float(arg)))
        depth += push
        deepest = max(deepest, depth)
        return len(code) - 2

    def check(e: Expr) -> None:
        if deepest > MAX_STACK:
            raise ExpressionError(e.line, e.column, f"the expression is nested too deeply "
                                  f"(it needs a value stack deeper than {MAX_STACK})")

    def expr(e: Expr) -> None:
        spine = _left_spine(e)  # left operand first, then each right operand and operator
        leaf = spine[-1].left if spine else e
        if isinstance(leaf, Num):
            emit(OP_CONST, leaf.value, 1)
        elif isinstance(leaf, Ref):
            st = leaf.field == "st"
            if leaf.name in outputs:
                emit(OP_LOAD_ST if st else OP_LOAD, outputs[leaf.name], 1)
            else:
                emit(OP_INPUT_ST if st else OP_INPUT, inputs[leaf.name], 1)
        elif isinstance(leaf, Unary):
            expr(leaf.operand)
            if leaf.op == "-":
                emit(OP_NEG)
            elif leaf.op == "NOT":
                emit(OP_NOT)
        check(leaf)
        for b in reversed(spine):
            expr(b.right)
            emit(_BINARY_OPS[b.op], 0.0, -1)
            check(b)

    def block(body: tuple[Statement, ...]) -> None:
        for s in body:
            if isinstance(s, Assign):
                expr(s.value)
                op = OP_STORE_ST if s.target.field == "st" else OP_STORE
                emit(op, outputs[s.target.name], -1)
                continue
            ends: list[int] = []
            for cond, branch in s.branches:
                expr(cond)
                skip = emit(OP_JUMP_IF_FALSE, 0.0, -1)
                block(branch)
                ends.append(emit(OP_JUMP))
                code[skip + 1] = float(len(code))
            block(s.orelse)
            for at in ends:
                code[at + 1] = float(len(code))

    block(prog.statements)
    return Compiled(code, max(deepest, 1))
