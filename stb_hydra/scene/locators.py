"""Data-source locators (Hydra 2.0) and the locator -> dirty-bit translation.

A locator names a piece of a prim's data ("xform", "light/params", ...). The
scene index reports *which* locators changed; the render index turns them into
the dirty bits each render prim understands (``DirtyBits``) via
:func:`dirty_bits_for`. USD attribute names are mapped to locators by
:func:`locator_for_attribute`.
"""

from __future__ import annotations

from enum import IntFlag

from . import prims


class DataSourceLocator(str):
    """A '/'-separated data path. ``a.has_prefix(b)`` is Hydra's HasPrefix."""

    __slots__ = ()

    def has_prefix(self, other: str) -> bool:
        return self == other or self.startswith(other + "/")

    def intersects(self, other: str) -> bool:
        return self.has_prefix(other) or DataSourceLocator(other).has_prefix(self)


L = DataSourceLocator

# Locators used by the stage scene index.
XFORM = L("xform")
VISIBILITY = L("visibility")
LIGHT = L("light")
LIGHT_PARAMS = L("light/params")
LIGHT_SHADOW = L("light/shadow")
LIGHT_COLLECTION = L("light/collection")
LIGHT_RESOURCE = L("light/resource")  # IES profile / dome texture files
POINTS = L("primvars/points")
NORMALS = L("primvars/normals")
PRIMVARS = L("primvars")  # every primvar
PRIMVARS_OTHER = L("primvars/other")  # primvars other than points/normals (displayColor...)
TOPOLOGY = L("mesh/topology")
MATERIAL_BINDINGS = L("materialBindings")
MATERIAL = L("material")
CAMERA_PARAMS = L("camera/params")
CAMERA_CLIP = L("camera/clippingPlanes")
INSTANCER = L("instancer")  # per-instance transforms of PointInstancer prototypes
#: A mesh's light-link / shadow-link groups (``scene/links.py``): set by the link
#: resolver when a collection or the geometry changed, never by a mesh attribute.
LINKS = L("linking")
STB = L("stb")  # stb:* attributes on geometry

#: Everything: used for "re-read the whole prim".
ALL = L("")


class DirtyBits(IntFlag):
    """Hydra-like change-tracker bits. One set serves every prim kind; each
    render prim only looks at the bits it understands."""

    Clean = 0
    DirtyTransform = 1 << 0
    DirtyVisibility = 1 << 1
    DirtyParams = 1 << 2
    DirtyShadowParams = 1 << 3
    DirtyCollection = 1 << 4
    DirtyResource = 1 << 5
    DirtyPoints = 1 << 6
    DirtyTopology = 1 << 7
    DirtyNormals = 1 << 8
    DirtyPrimvar = 1 << 9
    DirtyMaterialId = 1 << 10
    DirtyInstancer = 1 << 11
    DirtyClipPlanes = 1 << 12
    DirtyStbFlags = 1 << 13
    #: Hydra's DirtyCategories: a mesh's light/shadow-link membership (link groups).
    DirtyCategories = 1 << 14
    AllDirty = (1 << 15) - 1


D = DirtyBits

_LIGHT_BITS = {
    XFORM: D.DirtyTransform,
    VISIBILITY: D.DirtyVisibility | D.DirtyParams,
    LIGHT_PARAMS: D.DirtyParams,
    LIGHT_SHADOW: D.DirtyShadowParams,
    LIGHT_COLLECTION: D.DirtyCollection,
    LIGHT_RESOURCE: D.DirtyResource,
    LIGHT: D.DirtyParams | D.DirtyShadowParams | D.DirtyCollection | D.DirtyResource,
    INSTANCER: D.DirtyTransform,
}
_MESH_BITS = {
    XFORM: D.DirtyTransform,
    VISIBILITY: D.DirtyVisibility,
    POINTS: D.DirtyPoints,
    NORMALS: D.DirtyNormals,
    PRIMVARS_OTHER: D.DirtyPrimvar,
    PRIMVARS: D.DirtyPoints | D.DirtyNormals | D.DirtyPrimvar,
    TOPOLOGY: D.DirtyTopology | D.DirtyPoints | D.DirtyNormals,
    MATERIAL_BINDINGS: D.DirtyMaterialId,
    INSTANCER: D.DirtyInstancer,
    STB: D.DirtyStbFlags,
    LINKS: D.DirtyCategories,
}
_CAMERA_BITS = {
    XFORM: D.DirtyTransform,
    CAMERA_PARAMS: D.DirtyParams,
    CAMERA_CLIP: D.DirtyClipPlanes,
}
_MATERIAL_BITS = {MATERIAL: D.DirtyParams | D.DirtyResource}


def _table_for(prim_type: str) -> dict[DataSourceLocator, DirtyBits]:
    if prim_type in prims.LIGHT_TYPES:
        return _LIGHT_BITS
    if prim_type == prims.MESH:
        return _MESH_BITS
    if prim_type == prims.CAMERA:
        return _CAMERA_BITS
    if prim_type == prims.MATERIAL:
        return _MATERIAL_BITS
    return {}


def dirty_bits_for(prim_type: str, locators: frozenset[str] | set[str]) -> DirtyBits:
    """Translate a dirtied locator set into the render prim's dirty bits."""
    table = _table_for(prim_type)
    bits = D.Clean
    for loc in locators:
        exact = table.get(loc)
        if exact is not None:  # most specific first: "primvars/points" is not "primvars"
            bits |= exact
            continue
        loc = L(loc)
        if loc == ALL:
            return D.AllDirty
        coarse = [b for key, b in table.items() if L(key).has_prefix(loc)]
        if coarse:  # an ancestor locator dirties everything below it
            for b in coarse:
                bits |= b
            continue
        for key, b in table.items():  # a finer locator than any key: its parent's bits
            if loc.has_prefix(key):
                bits |= b
    return bits


# --- USD attribute name -> locator ------------------------------------------------------

_MESH_TOPOLOGY_ATTRS = frozenset(
    {
        "faceVertexCounts",
        "faceVertexIndices",
        "holeIndices",
        "orientation",
        "subdivisionScheme",
        # implicit shapes: their parameters define the tessellation
        "radius",
        "radiusTop",
        "radiusBottom",
        "height",
        "size",
        "axis",
        "width",
        "length",
    }
)


def locator_for_attribute(prim_type: str, name: str) -> DataSourceLocator | None:
    """Locator for a changed USD property ``name`` on a prim of ``prim_type``.

    Returns None for properties that do not affect rendering."""
    if name.startswith("xformOp") or name == "xformOpOrder":
        return XFORM
    if name == "visibility":
        return VISIBILITY
    if name == "purpose":
        return VISIBILITY
    if prim_type in prims.LIGHT_TYPES:
        bare = name[7:] if name.startswith("inputs:") else name
        if bare.startswith("shadow:") or name == "stb:shadow:update":
            return LIGHT_SHADOW
        if name.startswith("collection:"):
            return LIGHT_COLLECTION
        if bare in ("shaping:ies:file", "texture:file"):
            return LIGHT_RESOURCE
        if name.startswith(
            ("inputs:", "shaping:", "stb:", "light:", "treatAsPoint", "treatAsLine")
        ):
            return LIGHT_PARAMS
        # Pre-21.02 un-namespaced inputs (intensity, color, radius, ...).
        return LIGHT_PARAMS
    if prim_type == prims.MESH:
        if name == "points":
            return POINTS
        if name in ("normals", "primvars:normals", "primvars:normals:indices"):
            return NORMALS
        if name in _MESH_TOPOLOGY_ATTRS:
            return TOPOLOGY
        if name.startswith("material:binding"):
            return MATERIAL_BINDINGS
        if name.startswith("primvars:"):
            return PRIMVARS_OTHER
        if name.startswith("stb:"):
            return STB
        if name in ("doubleSided", "extent"):
            return PRIMVARS_OTHER if name == "doubleSided" else None
        return None
    if prim_type == prims.CAMERA:
        if name in ("clippingRange", "clippingPlanes"):
            return CAMERA_CLIP
        return CAMERA_PARAMS
    if prim_type == prims.MATERIAL:
        return MATERIAL
    return None
