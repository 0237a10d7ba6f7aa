"""Compile: class kernels, the index-1 residual with its sparse Jacobian, the ODE form, the linear form."""

from .system import CompiledSystem, compile_model

__all__ = ["CompiledSystem", "compile_model"]
