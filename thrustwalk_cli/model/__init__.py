"""SPEC 1: robot description -> SymPy derivation -> generated code -> cached compiled model.
SymPy is imported only by ``derive``, ``derive_reference`` and ``codegen``, and only when
compiling."""
