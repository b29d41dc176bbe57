"""Random material fields for :mod:`hetmesh.testing`: one formula of ``metal`` per family."""

from __future__ import annotations

import math

import numpy as np

from .geometry import Geometry, toml_float

__all__ = ["random_field", "FIELDS", "Box"]


class Box:
    """The domain's bounding box and the draws a family makes in it (``rng``: the model's)."""

    def __init__(self, rng, domain):
        self.rng = rng
        self.domain = domain
        self.x0, self.y0, self.x1, self.y1 = domain.bounds
        self.wx, self.wy = self.x1 - self.x0, self.y1 - self.y0
        self.D = max(self.wx, self.wy)
        self.xc, self.yc = 0.5 * (self.x0 + self.x1), 0.5 * (self.y0 + self.y1)

    def corners(self):
        """The four corners' coordinates as ``(cx, cy)`` pairs."""
        return [(cx, cy) for cx in (self.x0, self.x1) for cy in (self.y0, self.y1)]

    def any_point(self) -> np.ndarray:
        rng = self.rng
        return np.array([rng.uniform(self.x0, self.x1), rng.uniform(self.y0, self.y1)])

    def inside_point(self) -> np.ndarray:
        """A point inside the domain, off its boundary by 1 % of the box (else the centre)."""
        dom = self.domain
        for _ in range(500):
            p = self.any_point()
            if dom.contains(p[None])[0] and dom.distance_to_boundary(p[None])[0] > 0.01 * self.D:
                return p
        return np.array([self.xc, self.yc])

    def direction(self, axis_prob: float = 0.0) -> tuple[float, float]:
        """A unit direction, along an axis with probability ``axis_prob``."""
        rng = self.rng
        if rng.random() < axis_prob:
            th = rng.integers(0, 4) * 0.5 * math.pi
            c, s = round(math.cos(th)), round(math.sin(th))
        else:
            th = rng.uniform(0, 2 * math.pi)
            c, s = math.cos(th), math.sin(th)
        return float(c), float(s)

    def s_text(self, c: float, s: float) -> str:
        """The coordinate along (c, s), in domain widths, 0 at the box centre."""
        if s == 0.0:
            return "(x - xc)/D" if c > 0 else "(xc - x)/D"
        if c == 0.0:
            return "(y - yc)/D" if s > 0 else "(yc - y)/D"
        return f"((x - xc)*{toml_float(c)} + (y - yc)*{toml_float(s)})/D"

    def s_range(self, c: float, s: float) -> float:
        """Half the range of the s coordinate over the bounding box."""
        return (self.wx * abs(c) + self.wy * abs(s)) / (2.0 * self.D)

    def s_at(self, p, c, s) -> float:
        return ((p[0] - self.xc) * c + (p[1] - self.yc) * s) / self.D


def random_field(family: str, rng, geo: Geometry, domain):
    """The formula of ``metal``, its parameters and tags; in [0, 1] over the bounding box.

    ``FIELDS[family]`` draws the formula; every family may use ``lo`` and ``hi``, drawn
    first, and the box's ``xc``, ``yc`` and ``D``.
    """
    box = Box(rng, domain)
    params = {"xc": box.xc, "yc": box.yc, "D": box.D}
    tags: list[str] = []
    lo = float(rng.uniform(0.0, 0.3)) if rng.random() < 0.6 else 0.0
    hi = float(rng.uniform(0.7, 1.0)) if rng.random() < 0.6 else 1.0
    params.update(lo=lo, hi=hi)
    text = FIELDS[family](box, geo, params, tags)
    return text, params, tags


# ----------------------------------------------------------------------------- families
# Each draws one family's formula: (box, geometry, params, tags) -> text; it adds the
# parameters the formula uses to ``params`` and its tags to ``tags``.

def _gentle(box: Box, geo: Geometry, params: dict, tags: list) -> str:
    rng = box.rng
    variant = rng.choice(["linear", "quadratic", "bilinear", "bowl"])
    tags.append(str(variant))
    if variant in ("linear", "quadratic"):
        c, s = box.direction(0.3)
        params["sm"] = box.s_range(c, s)
        u = f"({box.s_text(c, s)} + sm)/(2*sm)"
        return f"lo + (hi - lo)*{u}" if variant == "linear" else f"lo + (hi - lo)*{u}**2"
    if variant == "bilinear":
        params.update(x0=box.x0, y0=box.y0, wx=box.wx, wy=box.wy)
        return "lo + (hi - lo)*((x - x0)/wx)*((y - y0)/wy)"
    p = box.any_point()
    d2 = max((cx - p[0]) ** 2 + (cy - p[1]) ** 2 for cx, cy in box.corners())
    params.update(px=float(p[0]), py=float(p[1]), d2=d2)
    return "lo + (hi - lo)*((x - px)**2 + (y - py)**2)/d2"


def _tanh(box: Box, geo: Geometry, params: dict, tags: list) -> str:
    rng = box.rng
    w = 10.0 ** rng.uniform(math.log10(0.005), math.log10(0.2))
    A = float(rng.uniform(0.7, 1.0))
    params.update(w=w, A=A)
    if w < 0.02:
        tags.append("steep")
    if rng.random() < 0.3:
        q = box.inside_point()
        r0 = float(rng.uniform(0.1, 0.45))
        params.update(px=float(q[0]), py=float(q[1]), r0=r0)
        tags.append("circular-front")
        return "0.5 + 0.5*A*tanh((sqrt((x - px)**2 + (y - py)**2)/D - r0)/w)"
    c, s = box.direction(0.2)
    params["s0"] = box.s_at(box.inside_point(), c, s)
    return f"0.5 + 0.5*A*tanh(({box.s_text(c, s)} - s0)/w)"


def _power(box: Box, geo: Geometry, params: dict, tags: list) -> str:
    rng = box.rng
    p = float(rng.uniform(0.5, 1.0)) if rng.random() < 0.4 else \
        float(10.0 ** rng.uniform(0.0, math.log10(8.0)))
    params["p"] = p
    if p < 1:
        tags.append("p<1")
    c, s = box.direction(0.7)
    at_edge = rng.random() < 0.6
    if c in (1.0, -1.0) and s == 0.0 or s in (1.0, -1.0) and c == 0.0:
        along_x = s == 0.0
        lo_edge = (box.x0 if c > 0 else box.x1) if along_x else (box.y0 if s > 0 else box.y1)
        span = box.wx if along_x else box.wy
        off = 0.0 if at_edge else float(rng.uniform(0.01, 0.1)) * span
        sign = (c if along_x else s)
        origin = lo_edge - sign * off
        var = "x" if along_x else "y"
        params.update({f"{var}0": origin, "L": span + off})
        base = f"({var} - {var}0)/L" if sign > 0 else f"({var}0 - {var})/L"
    else:
        sm = box.s_range(c, s)
        off = 0.0 if at_edge else float(rng.uniform(0.01, 0.1)) * 2 * sm
        params.update(s1=-sm - off, L=2 * sm + off)
        base = f"({box.s_text(c, s)} - s1)/L"
    if at_edge and p < 1:
        tags.append("edge-singular")
    return f"lo + (hi - lo)*max({base}, 0)**p"


def _sfgm(box: Box, geo: Geometry, params: dict, tags: list) -> str:
    rng = box.rng
    p = float(rng.uniform(0.5, 1.0)) if rng.random() < 0.3 else \
        float(10.0 ** rng.uniform(0.0, math.log10(8.0)))
    c, s = box.direction(0.4)
    sm = box.s_range(c, s)
    a = -sm + float(rng.uniform(0.0, 0.3)) * 2 * sm
    b = sm - float(rng.uniform(0.0, 0.3)) * 2 * sm
    if rng.random() < 0.3:  # no plateau
        a, b = -sm, sm
    params.update(p=p, a=a, bw=b - a)
    if p < 1:
        tags.append("p<1")
    if a > -sm or b < sm:
        tags.append("plateaus")
    u = f"clip(({box.s_text(c, s)} - a)/bw, 0, 1)"
    return f"lo + (hi - lo)*where({u} < 0.5, 0.5*(2*{u})**p, 1 - 0.5*(2 - 2*{u})**p)"


def _gaussian(box: Box, geo: Geometry, params: dict, tags: list) -> str:
    rng, D = box.rng, box.D
    lo, hi = params["lo"], params["hi"]
    k = int(rng.integers(1, 4))
    amps = rng.dirichlet(np.ones(k)) * (hi - lo) * float(rng.uniform(0.7, 1.0))
    terms = []
    dip = rng.random() < 0.3
    for i in range(k):
        q = box.inside_point() if rng.random() < 0.8 else box.any_point()
        sig = 10.0 ** rng.uniform(math.log10(0.02), math.log10(0.3))
        if sig < 0.05:
            tags.append("narrow")
        ratio = float(rng.uniform(1.0, 3.0)) if rng.random() < 0.5 else 1.0
        th = float(rng.uniform(0, math.pi))
        params.update({f"a{i}": float(amps[i]), f"cx{i}": float(q[0]), f"cy{i}": float(q[1]),
                       f"sa{i}": sig * D, f"sb{i}": sig * D / ratio})
        if ratio == 1.0:
            e = f"((x - cx{i})**2 + (y - cy{i})**2)/sa{i}**2"
        else:
            c, s = toml_float(math.cos(th)), toml_float(math.sin(th))
            e = (f"(((x - cx{i})*{c} + (y - cy{i})*{s})**2/sa{i}**2 + "
                 f"((y - cy{i})*{c} - (x - cx{i})*{s})**2/sb{i}**2)")
        terms.append(f"a{i}*exp(-0.5*{e})")
    tags.append("dip" if dip else "bump")
    tags[:] = list(dict.fromkeys(tags))
    return f"hi - ({' + '.join(terms)})" if dip else f"lo + {' + '.join(terms)}"


def _sines(box: Box, geo: Geometry, params: dict, tags: list) -> str:
    rng = box.rng
    k = 1 if rng.random() < 0.6 else 2
    amps = rng.dirichlet(np.ones(k)) * float(rng.uniform(0.5, 1.0))
    terms = []
    for i in range(k):
        kx, ky = (10.0 ** rng.uniform(math.log10(0.3), math.log10(3.0)) for _ in range(2))
        ph1, ph2 = (float(rng.uniform(0, 2 * math.pi)) for _ in range(2))
        params.update({f"a{i}": float(amps[i]), f"kx{i}": kx, f"ky{i}": ky,
                       f"ph{i}": ph1, f"ps{i}": ph2})
        terms.append(f"a{i}*sin(2*pi*kx{i}*(x - xc)/D + ph{i})*"
                     f"sin(2*pi*ky{i}*(y - yc)/D + ps{i})")
    tags.append("sines" if k == 1 else "sum-of-sines")
    return f"0.5 + 0.5*({' + '.join(terms)})"


def _kink(box: Box, geo: Geometry, params: dict, tags: list) -> str:
    rng = box.rng
    variant = rng.choice(["point", "corner", "line", "ridge"])
    if variant in ("point", "corner"):
        if variant == "corner":
            verts = [np.asarray(geo.start, float)] + [np.asarray(t, float)
                                                      for t, _, _ in geo.path[:-1]]
            q = verts[int(rng.integers(0, len(verts)))]
            tags.append("corner-kink")
        else:
            q = box.inside_point()
            tags.append("point-kink")
        dmax = max(math.hypot(cx - q[0], cy - q[1]) for cx, cy in box.corners())
        params.update(px=float(q[0]), py=float(q[1]), dm=dmax)
        dist = "sqrt((x - px)**2 + (y - py)**2)/dm"
        return f"lo + (hi - lo)*{dist}" if rng.random() < 0.5 else f"hi - (hi - lo)*{dist}"
    if variant == "line":
        c, s = box.direction(0.3)
        sm = box.s_range(c, s)
        c0 = box.s_at(box.inside_point(), c, s)
        params.update(c0=c0, cm=max(abs(-sm - c0), abs(sm - c0)))
        tags.append("line-kink")
        return f"lo + (hi - lo)*abs({box.s_text(c, s)} - c0)/cm"
    (c1, s1), (c2, s2) = box.direction(0.2), box.direction(0.2)
    m1, m2 = box.s_range(c1, s1), box.s_range(c2, s2)
    params.update(m1=m1, m2=m2)
    tags.append("ridge")
    return (f"lo + (hi - lo)*min(({box.s_text(c1, s1)} + m1)/(2*m1), "
            f"({box.s_text(c2, s2)} + m2)/(2*m2))")


#: The formula of every family (the keys are :data:`hetmesh.testing.FAMILIES`).
FIELDS = {"gentle": _gentle, "tanh": _tanh, "power": _power, "sfgm": _sfgm,
          "gaussian": _gaussian, "sines": _sines, "kink": _kink}
