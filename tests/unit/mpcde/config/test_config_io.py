"""config_io: typed conversion of YAML values, including both spellings of a union type."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import pytest

from mpcde.config.io import from_dict
from mpcde.errors import ConfigError


@dataclass(frozen=True)
class _Pep604:
    limit: float | None = None


@dataclass(frozen=True)
class _Typing:
    limit: Optional[float] = None


@pytest.mark.parametrize("cls", [_Pep604, _Typing])
def test_union_fields_convert_and_reject(cls):
    assert from_dict(cls, {"limit": None}).limit is None
    assert from_dict(cls, {"limit": 2}).limit == 2.0 and isinstance(from_dict(cls, {"limit": 2}).limit, float)
    assert from_dict(cls, {"limit": ".inf"}).limit == math.inf
    with pytest.raises(ConfigError) as e:
        from_dict(cls, {"limit": "soon"})
    assert "limit" in str(e.value) and "a number or null" in str(e.value)
