"""``stb render --ray`` and ``stb validate --ray``: the same work spread over a Ray
cluster (or a local Ray instance).

Ray is an optional extra (``pip install 'stb_hydra[ray]'``) imported lazily: nothing
here imports it at module level, so the package works without it. See
docs/ARCHITECTURE.md (Distributed runs) and README (Running on a Ray cluster).
"""
