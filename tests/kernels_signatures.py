"""How many times a compiled kernel was compiled for ε per system (the calls of mrs.velocity and
of the compiled loops must share one signature; ε per source, for scenes, is another)."""


def per_system(kernel, eps_index: int) -> list:
    """The signatures of ``kernel`` whose ε (argument ``eps_index``) is one per system, (B,)."""
    return [sig for sig in kernel.signatures if sig[eps_index].ndim == 1]
