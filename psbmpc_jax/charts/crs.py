"""Coordinate reference systems of charts: :class:`CRSInfo` and :func:`parse_crs` (EPSG codes, ``"UTM33N"``-style
names, OGC URNs and the WKT of ``.prj`` files).  WGS 84 and ETRS89 are treated as the same datum (see
:mod:`psbmpc_jax.charts`)."""

from __future__ import annotations

import re
from dataclasses import dataclass

from .utm import check_zone


@dataclass(frozen=True)
class CRSInfo:
    """A parsed coordinate reference system: UTM (``zone``, ``south``) or lon/lat, and the datum."""

    kind: str  # "utm" | "lonlat"
    datum: str  # "WGS84" | "ETRS89"
    zone: int | None = None
    south: bool = False

    @property
    def code(self) -> str:
        """Canonical ``"EPSG:nnnn"`` string."""
        if self.kind == "lonlat":
            return "EPSG:4258" if self.datum == "ETRS89" else "EPSG:4326"
        assert self.zone is not None            # a UTM CRS has a zone
        if self.datum == "ETRS89" and not self.south:
            return f"EPSG:{25800 + self.zone}"
        return f"EPSG:{(32700 if self.south else 32600) + self.zone}"

    @property
    def name(self) -> str:
        d = "ETRS89" if self.datum == "ETRS89" else "WGS 84"
        if self.kind == "lonlat":
            return f"{d} lon/lat ({self.code})"
        return f"{d} / UTM zone {self.zone}{'S' if self.south else 'N'} ({self.code})"

    def same_grid(self, other: "CRSInfo") -> bool:
        """Same projection and zone (datum WGS 84 vs ETRS89 ignored, see module docstring)."""
        return (self.kind, self.zone, self.south) == (other.kind, other.zone, other.south)


_ALLOWED_CRS = ("'EPSG:326zz', 'EPSG:327zz', 'EPSG:258zz' (UTM), 'EPSG:4326', 'EPSG:4258' (lon/lat), "
                "'UTM32N'-style names, or a WKT string with a UTM zone or a GEOGCS")


def parse_crs(text) -> CRSInfo:
    """Parse a CRS string (EPSG code, ``"UTM33N"``, OGC URN or WKT of a .prj file); ``ValueError`` if unknown."""
    if isinstance(text, CRSInfo):
        return text
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"CRS must be a non-empty string: {_ALLOWED_CRS}; got {text!r}")
    s = text.strip()
    up = s.upper()
    m = re.search(r"EPSG(?::|::|:\d*:)(\d+)$", up.replace("URN:OGC:DEF:CRS:", "")) or re.fullmatch(r"(\d{4,5})", up)
    if m:
        code = int(m.group(1))
        if code in (4326, 4258):
            return CRSInfo("lonlat", "ETRS89" if code == 4258 else "WGS84")
        if 32601 <= code <= 32660:
            return CRSInfo("utm", "WGS84", code - 32600, False)
        if 32701 <= code <= 32760:
            return CRSInfo("utm", "WGS84", code - 32700, True)
        if 25801 <= code <= 25860:
            return CRSInfo("utm", "ETRS89", code - 25800, False)
        raise ValueError(f"unsupported CRS {text!r}: allowed {_ALLOWED_CRS}")
    if up in ("CRS84", "OGC:CRS84", "URN:OGC:DEF:CRS:OGC:1.3:CRS84", "WGS84", "WGS 84"):
        return CRSInfo("lonlat", "WGS84")
    datum = "ETRS89" if ("ETRS" in up or "EUREF" in up or "GRS_1980" in up or "GRS 1980" in up) else "WGS84"
    m = re.search(r"UTM[ _]*(?:ZONE[ _]*)?(\d{1,2})\s*([NS])?\b", up)
    if m:
        zone = check_zone(int(m.group(1)))
        return CRSInfo("utm", datum, zone, m.group(2) == "S")
    if up.startswith("GEOGCS") or up.startswith("GEOGCRS"):
        return CRSInfo("lonlat", datum)
    raise ValueError(f"unsupported CRS {text[:120]!r}: allowed {_ALLOWED_CRS}")
