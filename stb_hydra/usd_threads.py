"""USD's worker threads (TBB's, through ``pxr.Work``) for this process.

oneTBB as bundled with usd-core 26.11: once TBB's worker threads have started -- and
``import stb_hydra`` starts them -- lowering the concurrency limit leaves them spinning
in ``sched_yield`` for the rest of the process (measured: an idle process lowered to 1
after ``import stb_hydra`` burnt 8.0 s of CPU in 8 s, 6.7 s of it sys; set before the
import: none). So code inside this package never lowers the limit: :func:`raise_limit`
only ever raises it. A process that wants fewer threads sets the limit itself before
it imports stb_hydra (``from pxr import Work; Work.SetConcurrencyLimit(n)``); the
test processes leave the default (docs/TESTING.md, "USD's threads in the workers")."""

from __future__ import annotations

__all__ = ["raise_limit"]


def raise_limit(n: int) -> int:
    """USD's concurrency limit raised to ``n`` threads if it is lower; a lower ``n`` is
    ignored (module docstring). Returns the limit in force."""
    from pxr import Work

    if n > Work.GetConcurrencyLimit():
        Work.SetConcurrencyLimit(int(n))
    return int(Work.GetConcurrencyLimit())
