"""The model as data: instruction tapes and their robot-independent interpreter.

A *tape* is what :func:`thrustwalk_cli.model.codegen.generate_tape` makes of the model's
SymPy expressions when a robot is compiled: a few *programs* (groups of outputs evaluated
together, sharing their common subexpressions), each a list of instructions on a register
file. The interpreter below is plain Python in the subset numba compiles; it is
compiled once per machine, for every robot, as part of the compiled simulation kernel and
of the batch evaluators (:mod:`thrustwalk_cli.model.jit`). So a new robot costs SymPy and the
translation into a tape (a fraction of a second), never a numba compile.

Layout of one program starting at ``code[p]`` (all integers)::

    n_in, n_out, n_ins, base, out_reg[0 .. n_out-1],
    then n_ins x (op << 57 | a << 38 | b << 19 | c)   instruction j: register base + j =
                                                      op(a, b, c) (c read by fma, fms, fnma)

Registers ``0 .. n_inputs-1`` hold the inputs (``q`` [rad] then ``q'`` [rad/s]; a program
reads the first ``n_in`` of them), then the constants of :attr:`Tape.consts`, then the
temporaries, each written once (measured: 30 % faster than reusing registers, and a few
kilobytes stay in the processor's first-level cache), and an instruction is one integer
(one load instead of three: 10-25 % faster); a product read once is folded into the sum
or difference that reads it (``a b + c``). Instructions are ordered by depth, so neighbours
rarely depend on each other. ``sin`` and ``cos`` of one register are one ``sincos``
instruction, which writes the sine into its own register and the cosine into the next (whose
instruction, ``skip``, does nothing): the compiler makes the two one ``sincos`` library call
(the same values; measured: a third cheaper than two calls). The batch interpreter runs
each instruction as a loop over a chunk of states.

Programs and their outputs (flat, row-major; N coordinates, m thrusters; SPEC 1, 5):

========== ===== =========================================================================
program    n_in  outputs
========== ===== =========================================================================
accel      2N    D (N*N), h = C q' + G (N), B_F (N*m)
force      2N    as accel, then rows N, N+1 of D_u (first N columns, 2*N), of h_u at
                 ``q_u' = [q'; 0; 0]`` (2) and of B_Fu (2*m): the ground force terms
height     N     swing-foot position p_2 (2)
footvel    2N    vertical swing-foot velocity ``E_2,y q'`` (1)
links      N     link_points (4 per link)
impact     N     D_u ((N+2)^2), E_2 = dp_2/dq_u (2*(N+2))
energy     N     D (N*N), V (1)
push       N     D (N*N), link_points_J (4 per link * N)
========== ===== =========================================================================
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

# operation codes (the interpreter below tests them in this order: most frequent first)
OP_MUL, OP_ADD, OP_SUB, OP_NEG, OP_SIN, OP_COS, OP_DIV, OP_POW = range(8)
OP_FMA, OP_FMS, OP_FNMA = 8, 9, 10  # a b + c, a b - c, c - a b
OP_SINCOS, OP_SKIP = 11, 12  # sin a (cos a into the next register), the next's placeholder
OPS = {"mul": OP_MUL, "add": OP_ADD, "sub": OP_SUB, "neg": OP_NEG, "sin": OP_SIN,
       "cos": OP_COS, "div": OP_DIV, "pow": OP_POW, "fma": OP_FMA, "fms": OP_FMS,
       "fnma": OP_FNMA, "sincos": OP_SINCOS, "skip": OP_SKIP}
PROGRAMS = ("accel", "force", "height", "footvel", "links", "impact", "energy", "push")


@dataclass(frozen=True)
class Tape:
    """A robot's tape: ``code`` (int64), ``consts`` (float64, registers ``n_inputs ..``),
    ``programs`` (name -> offset in ``code``), ``nreg`` registers, ``n_inputs`` (2N).

    ``code`` depends on the robot's structure alone; ``consts`` holds the numbers of the
    code and the coefficients computed from the robot's numbers (the model binds them), so
    the interpreters read every number from an input array and one ``code`` serves every
    value of the robot's numbers."""

    code: np.ndarray
    consts: np.ndarray
    programs: dict
    nreg: int
    n_inputs: int

    @classmethod
    def from_data(cls, data: dict, consts=None) -> Tape:
        """The tape of generated ``data``; ``consts``: the bound constants (a list as long
        as ``data["consts"]``, whose entries name the coefficients of the numbers)."""
        code = _CODE.get(id(data))
        if code is None or code[0] is not data:
            code = (data, np.asarray(data["code"], np.int64))
            _CODE[id(data)] = code
        c = np.asarray(data["consts"] if consts is None else consts, float)
        return cls(code[1], c, dict(data["programs"]), int(data["nreg"]),
                   int(data["n_inputs"]))

    def n_out(self, program: str) -> int:
        """The number of outputs of the program named ``program``."""
        return int(self.code[self.programs[program] + 1])

    def instructions(self, program: str | None = None) -> int:
        """Number of instructions of one program (or of all)."""
        names = [program] if program else list(self.programs)
        return sum(int(self.code[self.programs[name] + 2]) for name in names)

    def registers(self) -> np.ndarray:
        """A register file with the constants in place (inputs and temporaries zero)."""
        r = np.zeros(self.nreg)
        r[self.n_inputs:self.n_inputs + self.consts.size] = self.consts
        return r


_CODE: dict[int, tuple[dict, np.ndarray]] = {}  # one code array per generated tape


# ------------------------------------------------------------------ interpreter (numba)
# Plain Python that numba compiles (see jit.py); the op codes are repeated as literals so
# the functions need no globals.
def tape_run(code, p, x, r, o):
    """Run the program at ``code[p]``: inputs ``x[:n_in]`` into the registers ``r`` (whose
    constants are in place), outputs into ``r[o:o + n_out]`` (an offset rather than a view:
    a view costs two atomic reference-count updates per call). Register numbers are unsigned
    inside the loop: numba then skips its negative-index correction (measured: 12-15 %
    faster)."""
    n_in = code[p]
    n_out = code[p + 1]
    for i in range(n_in):
        r[i] = x[i]
    k0 = np.uint64(p + 4 + n_out)
    base = np.uint64(code[p + 3])
    mask = np.uint64(524287)
    sa, sb, sop = np.uint64(38), np.uint64(19), np.uint64(57)
    one = np.uint64(1)
    for j in range(code[p + 2]):
        uj = np.uint64(j)
        c = np.uint64(code[k0 + uj])
        op = c >> sop
        a = r[(c >> sa) & mask]
        b = r[(c >> sb) & mask]
        if op == 0:
            v = a * b
        elif op == 8:
            v = a * b + r[c & mask]
        elif op == 1:
            v = a + b
        elif op == 2:
            v = a - b
        elif op == 10:
            v = r[c & mask] - a * b
        elif op == 9:
            v = a * b - r[c & mask]
        elif op == 3:
            v = -a
        elif op == 11:
            v = np.sin(a)
            r[base + uj + one] = np.cos(a)  # (one sincos call)
        elif op == 12:
            v = r[base + uj]  # written by the sincos before it (no `continue`: measured
            # 20 % slower loop)
        elif op == 4:
            v = np.sin(a)
        elif op == 5:
            v = np.cos(a)
        elif op == 6:
            v = a / b
        else:
            v = a ** b
        r[base + uj] = v
    k = p + 4
    for i in range(n_out):
        r[o + i] = r[code[k + i]]
    return n_out


def tape_batch(code, p, consts, c0, nreg, X, out, chunk):
    """Run the program at ``code[p]`` for every row of ``X`` (states, inputs) into the rows
    of ``out`` (states, outputs), ``chunk`` states at a time: each instruction is a loop
    over the states of the chunk (registers are rows of a (nreg, chunk) array)."""
    return tape_chunks(code, p, consts, c0, np.empty((nreg, chunk)), X, out)


def tape_chunks(code, p, consts, c0, r, X, out):
    """:func:`tape_batch` with its registers ``r`` (nreg, chunk) given: allocates nothing,
    so it is compiled without reference counting (the four row views an instruction takes
    cost no atomic updates; measured: about twice as fast)."""
    n_in = code[p]
    n_out = code[p + 1]
    base = code[p + 3]
    K = X.shape[0]
    chunk = r.shape[1]
    for i in range(consts.shape[0]):
        for s in range(chunk):
            r[c0 + i, s] = consts[i]
    k0 = p + 4 + n_out
    for lo in range(0, K, chunk):
        n = min(K, lo + chunk) - lo
        for i in range(n_in):
            ri = r[i]
            for s in range(n):
                ri[s] = X[lo + s, i]
        for j in range(code[p + 2]):
            c = code[k0 + j]
            op = c >> 57
            rd = r[base + j]
            ra = r[(c >> 38) & 524287]
            rb = r[(c >> 19) & 524287]
            rc = r[c & 524287]
            if op == 0:
                for s in range(n):
                    rd[s] = ra[s] * rb[s]
            elif op == 8:
                for s in range(n):
                    rd[s] = ra[s] * rb[s] + rc[s]
            elif op == 9:
                for s in range(n):
                    rd[s] = ra[s] * rb[s] - rc[s]
            elif op == 10:
                for s in range(n):
                    rd[s] = rc[s] - ra[s] * rb[s]
            elif op == 1:
                for s in range(n):
                    rd[s] = ra[s] + rb[s]
            elif op == 2:
                for s in range(n):
                    rd[s] = ra[s] - rb[s]
            elif op == 3:
                for s in range(n):
                    rd[s] = -ra[s]
            elif op == 11:
                rn = r[base + j + 1]
                for s in range(n):
                    v = ra[s]
                    rd[s] = np.sin(v)
                    rn[s] = np.cos(v)  # (one sincos call)
            elif op == 12:
                pass
            elif op == 4:
                for s in range(n):
                    rd[s] = np.sin(ra[s])
            elif op == 5:
                for s in range(n):
                    rd[s] = np.cos(ra[s])
            elif op == 6:
                for s in range(n):
                    rd[s] = ra[s] / rb[s]
            else:
                for s in range(n):
                    rd[s] = ra[s] ** rb[s]
        o = p + 4
        for i in range(n_out):
            ro = r[code[o + i]]
            for s in range(n):
                out[lo + s, i] = ro[s]
    return K


SIGNATURES = {
    "tape_run": "(int64[::1], int64, float64[::1], float64[::1], int64)",
    "tape_chunks": "(int64[::1], int64, float64[::1], int64, float64[:, ::1], "
                   "float64[:, ::1], float64[:, ::1])",
    "tape_batch": "(int64[::1], int64, float64[::1], int64, int64, float64[:, ::1], "
                  "float64[:, ::1], int64)",
}
NRT_FREE = frozenset({"tape_run", "tape_chunks"})  # allocate nothing (see model/jit.py)


def interpreter_source() -> str:
    """The interpreter's source, for the jit modules that compile it."""
    return "\n\n".join(inspect.getsource(f) for f in (tape_run, tape_batch, tape_chunks))
