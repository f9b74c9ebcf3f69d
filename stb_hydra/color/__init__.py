"""Colour: OCIO pipeline (``ocio``) and shared colorimetric constants."""

#: Rec.709 / sRGB relative luminance weights (Y of linear R, G, B), ITU-R BT.709.
LUMINANCE_REC709: tuple[float, float, float] = (0.2126, 0.7152, 0.0722)

__all__ = ["LUMINANCE_REC709"]
