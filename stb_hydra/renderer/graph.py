"""The frame's pass graph: passes declare what they read and write; the graph is
ordered, checked, culled and described from those declarations when it is built.

Resources are descriptors (data, no GL):

* :class:`Tex` - a render-buffer texture by name, with a format (``"rgba16f"``...)
  and a size policy (:class:`Size`): the graph allocates it at the viewport size.
* :class:`Rec` - a typed per-frame CPU record (a class from ``records.py``), kept on
  the :class:`~stb_hydra.renderer.frame.FrameContext`, never on the delegate.
* :class:`Imported` - something that outlives the frame and is owned elsewhere
  (the delegate's light table and meshes, the OCIO pipeline): never "missing".

A pass (``tasks/base.Pass``) lists ``reads`` and ``writes``. A resource has one
producer (a pass that writes it without reading it); passes that read *and* write
it modify it in place and run after the producer and before the plain readers.
:func:`compile_graph` maps each resource to its producer, refuses a read that no
scheduled pass writes (naming reader, resource and - where one exists - the
registered pass that could write it but is off), sorts the passes (Kahn, ties
broken by registration order), culls passes whose outputs nothing needs (unless
the pass has ``side_effect``), checks formats, and records first/last use for
:meth:`CompiledGraph.describe`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Generic, Protocol, TypeVar

#: Texture formats: name -> (components, moderngl dtype).
FORMATS: dict[str, tuple[int, str]] = {
    "r8": (1, "f1"),
    "rgba8": (4, "f1"),
    "r16f": (1, "f2"),
    "rg16f": (2, "f2"),
    "rgba16f": (4, "f2"),
    "r32f": (1, "f4"),
    "rg32f": (2, "f4"),
    "rgba32f": (4, "f4"),
    "r8ui": (1, "u1"),
    "r32ui": (1, "u4"),
    "rgba32ui": (4, "u4"),
    "depth24": (1, "depth"),
}


class GraphError(ValueError):
    """The pass graph cannot run (a read nobody writes, a cycle, a format clash)."""


@dataclass(frozen=True)
class Size:
    """A texture's size policy: the viewport divided by ``divisor`` (rounded up), or
    ``fixed`` texels, or ``derived`` (the writing pass sizes it each frame)."""

    divisor: int = 1
    fixed: tuple[int, int] | None = None
    derived: bool = False

    def resolve(self, width: int, height: int) -> tuple[int, int] | None:
        if self.derived:
            return None
        if self.fixed is not None:
            return self.fixed
        d = self.divisor
        return (max(1, -(-width // d)), max(1, -(-height // d)))

    def __str__(self) -> str:
        if self.derived:
            return "derived"
        if self.fixed is not None:
            return f"{self.fixed[0]}x{self.fixed[1]}"
        return "full" if self.divisor == 1 else f"1/{self.divisor}"


FULL = Size()
DERIVED = Size(derived=True)


@dataclass(frozen=True)
class Tex:
    """A render-buffer texture. ``fmt`` None on a read: any format."""

    name: str
    fmt: str | None = None
    size: Size = FULL
    optional: bool = False

    @property
    def key(self) -> str:
        return self.name

    def __str__(self) -> str:
        return f"{self.name} ({self.fmt or 'any'}, {self.size})"


@dataclass(frozen=True)
class Rec:
    """A typed per-frame record (an instance of ``cls`` on the frame context)."""

    cls: type
    optional: bool = False

    @property
    def key(self) -> str:
        return self.cls.__name__

    def __str__(self) -> str:
        return f"{self.cls.__name__} (record)"


@dataclass(frozen=True)
class Imported:
    """A resource owned outside the graph (delegate, colour pipeline)."""

    name: str
    optional: bool = False

    @property
    def key(self) -> str:
        return self.name

    def __str__(self) -> str:
        return f"{self.name} (imported)"


Resource = Tex | Rec | Imported


class GraphNode(Protocol):
    """What the graph reads of a pass (``tasks/base.Pass`` is one): its name, flags
    and declared ``(reads, writes)``. A protocol, so the graph does not import the
    passes that import its resource types."""

    @property
    def name(self) -> str: ...

    @property
    def only_final(self) -> bool: ...

    @property
    def side_effect(self) -> bool: ...

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]: ...


#: The concrete pass type a graph is compiled from (and hands back in order).
Pass = TypeVar("Pass", bound=GraphNode)


@dataclass
class CompiledGraph(Generic[Pass]):
    """The scheduled passes in execution order and the resources they use."""

    passes: list[Pass]
    culled: list[str]
    resources: dict[str, Resource]
    producer: dict[str, str]
    first_use: dict[str, str] = field(default_factory=dict)
    last_use: dict[str, str] = field(default_factory=dict)

    def textures(self) -> list[Tex]:
        """Textures the graph allocates (writes with a format), in first-use order."""
        return [r for r in self.resources.values() if isinstance(r, Tex) and r.fmt]

    def describe(self, size: tuple[int, int] | None = None) -> str:
        """The graph as text: passes in order with reads/writes, then resources."""
        lines = ["passes (execution order):"]
        for i, p in enumerate(self.passes):
            flags = [
                f for f, on in (("final-only", p.only_final), ("side-effect", p.side_effect)) if on
            ]
            lines.append(f"  {i + 1:2d}. {p.name}" + (f"  [{', '.join(flags)}]" if flags else ""))
            reads, writes = p.io()
            if reads:
                lines.append("        reads:  " + ", ".join(sorted(r.key for r in reads)))
            if writes:
                lines.append("        writes: " + ", ".join(sorted(r.key for r in writes)))
        if self.culled:
            lines.append("culled (outputs unused): " + ", ".join(self.culled))
        lines.append("resources:")
        for key, r in self.resources.items():
            desc = str(r)
            if size is not None and isinstance(r, Tex):
                wh = r.size.resolve(*size)
                if wh is not None:
                    desc += f" = {wh[0]}x{wh[1]}"
            prod = self.producer.get(key, "imported" if isinstance(r, Imported) else "-")
            lines.append(
                f"  {desc:<44} by {prod:<18} used {self.first_use.get(key, '-')}"
                f" .. {self.last_use.get(key, '-')}"
            )
        return "\n".join(lines)


def _writers(passes: Sequence[Pass]) -> tuple[dict[str, str], dict[str, list[str]]]:
    producer: dict[str, str] = {}
    modifiers: dict[str, list[str]] = {}
    for p in passes:
        reads, writes = p.io()
        read_keys = {r.key for r in reads}
        for w in writes:
            if w.key in read_keys:
                modifiers.setdefault(w.key, []).append(p.name)
            elif w.key in producer:
                raise GraphError(
                    f"'{w.key}' is written by both '{producer[w.key]}' and '{p.name}' "
                    "(a second writer must also read it)"
                )
            else:
                producer[w.key] = p.name
    return producer, modifiers


def _edges(
    passes: Sequence[Pass],
    producer: dict[str, str],
    modifiers: dict[str, list[str]],
    imports: set[str],
    off: dict[str, str],
) -> dict[str, set[str]]:
    """pass -> passes it depends on; raises on an unsatisfied read."""
    deps: dict[str, set[str]] = {p.name: set() for p in passes}
    for p in passes:
        reads, writes = p.io()
        write_keys = {w.key for w in writes}
        for r in reads:
            if r.key in imports:
                continue
            src = producer.get(r.key)
            if src is None:
                if r.optional:
                    continue
                hint = off.get(r.key)
                raise GraphError(
                    f"pass '{p.name}' reads {r} but no scheduled pass writes it"
                    + (f"; {hint}" if hint else "")
                )
            mods = modifiers.get(r.key, [])
            if r.key in write_keys:  # a modifier: after the producer and earlier modifiers
                before = mods[: mods.index(p.name)]
                deps[p.name].update([src, *before])
            else:
                deps[p.name].update([src, *mods])
        deps[p.name].discard(p.name)
    return deps


def _sort(passes: Sequence[Pass], deps: dict[str, set[str]]) -> list[Pass]:
    order = {p.name: i for i, p in enumerate(passes)}
    by_name = {p.name: p for p in passes}
    remaining = {k: set(v) for k, v in deps.items()}
    out: list[Pass] = []
    while remaining:
        ready = sorted((n for n, d in remaining.items() if not d), key=order.__getitem__)
        if not ready:
            raise GraphError("cycle between passes: " + ", ".join(sorted(remaining)))
        n = ready[0]
        out.append(by_name[n])
        del remaining[n]
        for d in remaining.values():
            d.discard(n)
    return out


def _cull(ordered: list[Pass], deps: dict[str, set[str]]) -> tuple[list[Pass], list[str]]:
    needed = {p.name for p in ordered if p.side_effect}
    for p in reversed(ordered):
        if p.name in needed:
            needed |= deps[p.name]
    return [p for p in ordered if p.name in needed], [
        p.name for p in ordered if p.name not in needed
    ]


def _check_formats(passes: Sequence[Pass], resources: dict[str, Resource]) -> None:
    for p in passes:
        reads, _ = p.io()
        for r in reads:
            have = resources.get(r.key)
            if isinstance(r, Tex) and r.fmt and isinstance(have, Tex) and have.fmt:
                if have.fmt != r.fmt:
                    raise GraphError(
                        f"pass '{p.name}' reads {r.name} as {r.fmt} but it is written as {have.fmt}"
                    )


def compile_graph(
    passes: Iterable[Pass],
    imports: Iterable[str] = (),
    off: dict[str, str] | None = None,
) -> CompiledGraph[Pass]:
    """Order, check and cull ``passes`` (in registration order).

    ``imports``: resource names owned outside the graph. ``off``: resource key ->
    why the registered pass that would write it is not scheduled (for errors).
    """
    passes = list(passes)
    names = [p.name for p in passes]
    if len(set(names)) != len(names):
        raise GraphError("two passes share a name: " + ", ".join(names))
    producer, modifiers = _writers(passes)
    deps = _edges(passes, producer, modifiers, set(imports), off or {})
    ordered = _sort(passes, deps)
    scheduled, culled = _cull(ordered, deps)
    resources: dict[str, Resource] = {}
    first: dict[str, str] = {}
    last: dict[str, str] = {}
    for p in scheduled:
        reads, writes = p.io()
        for w in writes:
            if w.key not in resources or (isinstance(w, Tex) and w.fmt):
                resources[w.key] = w
        for r in (*reads, *writes):
            resources.setdefault(r.key, r)
            first.setdefault(r.key, p.name)
            last[r.key] = p.name
    _check_formats(scheduled, resources)
    return CompiledGraph(scheduled, culled, resources, producer, first, last)


__all__ = [
    "DERIVED",
    "FORMATS",
    "FULL",
    "CompiledGraph",
    "GraphError",
    "Imported",
    "Rec",
    "Resource",
    "Size",
    "Tex",
    "compile_graph",
]
