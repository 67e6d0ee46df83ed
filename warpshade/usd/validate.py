"""Compliance check of USD outputs with every registered ``pxr.UsdValidation`` validator (docs/conventions.md §6)."""

from __future__ import annotations

from pxr import Usd, UsdValidation


def validation_errors(stage_or_path) -> list[str]:
    """Errors (not warnings) that all registered validators report, as ``"name: message"`` strings.

    Args:
        stage_or_path: A ``Usd.Stage`` or a file path.
    """
    stage = stage_or_path if isinstance(stage_or_path, Usd.Stage) else Usd.Stage.Open(str(stage_or_path))
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    return [f"{e.GetName()}: {e.GetMessage()}" for e in ctx.Validate(stage)
            if e.GetType() == UsdValidation.ValidationErrorType.Error]
