"""High-precision reference of the linear oscillator's response, independent of vmj's formula:
`m x'' + c x' + k x = Qr sin(p t) + Qi cos(p t)` written as the linear system `y' = A y` of
`y = (x, v, sin p t, cos p t)`, and `y(t) = exp(A t) y(0)` by scaling and squaring of the
Taylor series in Python's `decimal` at 60 significant digits. No roots, no divided differences:
the same program serves under-, critically and over-damped, resonant and undamped cases. The
float64 inputs are converted exactly (`Decimal(float)`), so the result is the exact response of
the rounded parameters to about 1e-50 relative (the series' truncation 1e-60 times the growth
of 2^s squarings)."""

from decimal import Decimal, localcontext

DIGITS = 60


def _matmul(a, b):
    n = len(a)
    return [[sum(a[i][k] * b[k][j] for k in range(n)) for j in range(n)] for i in range(n)]


def _expm(a):
    n = len(a)
    norm = max(sum(abs(x) for x in row) for row in a)
    s = 0
    while norm > Decimal("0.5"):
        norm /= 2
        s += 1
    scaled = [[x / (2**s) for x in row] for row in a]
    out = [[Decimal(int(i == j)) for j in range(n)] for i in range(n)]
    term = [row[:] for row in out]
    eps = Decimal(10) ** (-DIGITS - 5)
    for j in range(1, 200):
        term = [[x / j for x in row] for row in _matmul(term, scaled)]
        out = [[x + y for x, y in zip(r, q)] for r, q in zip(out, term)]
        if max(abs(x) for row in term for x in row) < eps:
            break
    for _ in range(s):
        out = _matmul(out, out)
    return out


def _solve(m, c, k, Qr, Qi, p, x0, v0, ts):
    """`(x, v)` lists of `Decimal`s (arguments `Decimal`s, within a 60-digit context)."""
    a = [
        [Decimal(0), Decimal(1), Decimal(0), Decimal(0)],
        [-k / m, -c / m, Qr / m, Qi / m],
        [Decimal(0), Decimal(0), Decimal(0), p],
        [Decimal(0), Decimal(0), -p, Decimal(0)],
    ]
    y0 = [x0, v0, Decimal(0), Decimal(1)]
    xs, vs = [], []
    for t in ts:
        e = _expm([[x * Decimal(t) for x in row] for row in a])
        xs.append(sum(e[0][j] * y0[j] for j in range(4)))
        vs.append(sum(e[1][j] * y0[j] for j in range(4)))
    return xs, vs


def response(m, c, k, Qr, Qi, p, x0, v0, ts):
    """`(x, v)` lists of floats at the times `ts` (all arguments floats, converted exactly)."""
    with localcontext() as ctx:
        ctx.prec = DIGITS
        xs, vs = _solve(*map(Decimal, (m, c, k, Qr, Qi, p, x0, v0)), ts)
        return [float(x) for x in xs], [float(v) for v in vs]


def derivative(name, m, c, k, Qr, Qi, p, x0, v0, ts):
    """`dx/d name` at the times `ts` (floats), `name` one of `"c"`, `"k"`, `"p"`: a central
    difference of step 1e-22 in 60-digit arithmetic (truncation about 1e-44, rounding about
    1e-38 relative). The force's amplitude `Qr + i Qi` is held fixed."""
    with localcontext() as ctx:
        ctx.prec = DIGITS
        args = dict(zip("m c k Qr Qi p x0 v0".split(), map(Decimal, (m, c, k, Qr, Qi, p, x0, v0))))
        h = Decimal("1e-22")
        up, down = dict(args), dict(args)
        up[name] += h
        down[name] -= h
        xu, _ = _solve(*up.values(), ts)
        xd, _ = _solve(*down.values(), ts)
        return [float((a - b) / (2 * h)) for a, b in zip(xu, xd)]
