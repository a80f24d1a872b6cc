from __future__ import annotations

import galileo_async


def test_version_is_exported() -> None:
    assert galileo_async.__version__ == "0.1.0"
