"""qdplot's figures, one module per kind. A kind is a function of the output and either an
environment's groups of runs ("per environment") or one run, the group's example ("per algorithm"):
add a module and an entry to KINDS for a new one (the map of a CVT archive is a map drawn by
another module, voronoi, chosen by the run's grid.toml)."""
from . import coverage, latents, losses, maps, qd, traces

# kind -> (scope, what it needs from qdrun)
KINDS = {
    "coverage": ("environment", False),
    "qd": ("environment", False),
    "maps": ("run", False),
    "traces": ("run", True),
    "latents": ("run", True),
    "losses": ("run", False),
}
COLORS = ("occupancy", "fitness")


def draw(kind, out, target, qdrun=None, colors=COLORS):
    """Draws one figure kind for an environment's groups (`target` = (env, groups)) or a run."""
    if kind == "coverage":
        env, groups = target
        coverage.plot(out, env, groups)
    elif kind == "qd":
        env, groups = target
        qd.plot(out, env, groups)
    elif kind == "maps":
        maps.plot(out, target, colors)
    elif kind == "traces":
        traces.plot(out, target, qdrun)
    elif kind == "latents":
        latents.plot(out, target, qdrun)
    elif kind == "losses":
        losses.plot(out, target)
    else:
        raise ValueError(kind)
