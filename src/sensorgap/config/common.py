"""Shared pydantic building blocks: strict, finite numbers and a base model."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

#: A finite float (NaN and +-inf rejected on load).
Finite = Annotated[float, Field(allow_inf_nan=False)]
#: A finite float >= 0.
NonNeg = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
#: A finite float > 0.
Positive = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]


class Strict(BaseModel):
    """Base for config models: unknown keys are errors, numbers must be finite, and no type
    coercion (a quoted "3" is not a number; integers are accepted where floats are)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)
