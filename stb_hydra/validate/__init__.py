"""Asset-library light validation on OpenUSD's UsdValidation framework (``stb validate``).

Importing this package registers our validators with
``UsdValidation.ValidationRegistry()`` under the keyword ``stb`` (see
:mod:`.plugin`); the rule table is :data:`.findings.RULES` and docs/VALIDATE.md.
``validate_file`` / ``validate_paths`` (in :mod:`.runner`) run them together with the
relevant built-in validators on asset files.
"""

from __future__ import annotations

import stb_hydra  # noqa: F401  (schema registration before any stage opens)

from .findings import KEYWORD, PLUGIN_NAME, RULES, AssetReport, Finding
from .plugin import register_plugin, register_validators

register_plugin()
VALIDATOR_NAMES = register_validators()

__all__ = [
    "KEYWORD",
    "PLUGIN_NAME",
    "RULES",
    "VALIDATOR_NAMES",
    "AssetReport",
    "Finding",
]
