"""``GET /favicon.ico``: the server's icon, which browsers ask for on every page of their own
(the leaderboard's pages name an SVG one; the live view, the API's docs and an address typed by
hand do not). The leaderboard's icon, drawn as an ICO of 16, 32 and 48 pixels: a dark square
with the three goals' colours."""

from __future__ import annotations

import functools
import io

from fastapi import APIRouter
from fastapi.responses import Response
from PIL import Image, ImageDraw

ICON_PATH = "/favicon.ico"
SIZES = (16, 32, 48)
SCALE = 16
"""The drawing is on a 16-unit square, as the leaderboard's ``favicon.svg``."""
BACKGROUND = "#18324a"
DOTS = (((5.0, 11.0), "#e8413c"), ((8.0, 5.0), "#3a7bd5"), ((11.5, 10.0), "#f2c230"))
"""Centre (units) and colour of each goal dot, radius 2.2 units."""

router = APIRouter(include_in_schema=False)


@functools.cache
def icon_bytes() -> bytes:
    """The ICO file (drawn once, large, then scaled down by the ICO writer)."""
    size = 16 * max(SIZES)
    unit = size / SCALE
    image = Image.new("RGBA", (size, size), (0, 0, 0, 0))
    draw = ImageDraw.Draw(image)
    draw.rounded_rectangle([0, 0, size - 1, size - 1], radius=3 * unit, fill=BACKGROUND)
    for (x, y), colour in DOTS:
        cx, cy, r = x * unit, y * unit, 2.2 * unit
        draw.ellipse([cx - r, cy - r, cx + r, cy + r], fill=colour)
    buffer = io.BytesIO()
    image.save(buffer, format="ICO", sizes=[(s, s) for s in SIZES])
    return buffer.getvalue()


@router.get(ICON_PATH)
async def favicon() -> Response:
    return Response(
        icon_bytes(),
        media_type="image/vnd.microsoft.icon",
        headers={"Cache-Control": "public, max-age=86400"},
    )
