"""PyTorch side of the autoencoder benchmark (run by compare_pytorch.sh with /usr/bin/python3).

The same model and workload as autoencoder_bench: P -> 100 (ELU) -> 50 -> 100 (ELU) -> P, float32,
Adam lr 1e-5, batch 64 from a fresh permutation per epoch, loss = per-sample SSE averaged over
the batch. Prints `key value` lines.

usage: torch_bench.py THREADS [--n 5000] [--p 2052] [--epochs 5] [--parents 200] [--sigma 0.1]
                               [--offspring 1|0]
"""
import argparse
import ctypes
import math
import time

import torch

ap = argparse.ArgumentParser()
ap.add_argument("threads", type=int)
ap.add_argument("--n", type=int, default=5000)
ap.add_argument("--p", type=int, default=2052)
ap.add_argument("--epochs", type=int, default=5)
ap.add_argument("--parents", type=int, default=200)
ap.add_argument("--sigma", type=float, default=0.1)
ap.add_argument("--offspring", type=int, default=1)
args = ap.parse_args()

torch.set_num_threads(args.threads)
torch.manual_seed(0)


def openblas():
    """The OpenBLAS library PyTorch loaded (None when it is not OpenBLAS)."""
    torch.ones(4, 4) @ torch.ones(4, 4)  # make sure BLAS is loaded
    with open("/proc/self/maps") as maps:
        paths = {line.split()[-1] for line in maps if "openblas" in line and ".so" in line}
    for path in sorted(paths):
        if "libopenblas" in path:
            return ctypes.CDLL(path)
    return None


blas = openblas()
if blas is None:
    raise SystemExit("PyTorch did not load OpenBLAS")
blas.openblas_get_corename.restype = ctypes.c_char_p
blas.openblas_set_num_threads(args.threads)
print("torch_version", torch.__version__)
print("torch_blas_core", blas.openblas_get_corename().decode())
print("torch_blas_threads", blas.openblas_get_num_threads())


class AE(torch.nn.Module):
    def __init__(self, p, hidden=100, latent=50):
        super().__init__()
        self.e1 = torch.nn.Linear(p, hidden)
        self.e2 = torch.nn.Linear(hidden, latent)
        self.d1 = torch.nn.Linear(latent, hidden)
        self.d2 = torch.nn.Linear(hidden, p)
        for layer in (self.e1, self.e2, self.d1, self.d2):
            torch.nn.init.xavier_uniform_(layer.weight)
            torch.nn.init.zeros_(layer.bias)

    def encode(self, x):
        return self.e2(torch.nn.functional.elu(self.e1(x)))

    def decode(self, z):
        return self.d2(torch.nn.functional.elu(self.d1(z)))

    def forward(self, x):
        return self.decode(self.encode(x))


x = torch.rand(args.n, args.p) * 2 - 1
model = AE(args.p)
opt = torch.optim.Adam(model.parameters(), lr=1e-5, betas=(0.9, 0.999), eps=1e-8)


def epoch():
    perm = torch.randperm(args.n)
    for start in range(0, args.n, 64):
        xb = x[perm[start:start + 64]]
        loss = ((model(xb) - xb) ** 2).sum(dim=1).mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()


epoch()  # warm-up
# The fastest single epoch: the machine is shared, and the minimum is the least disturbed figure.
best_epoch = math.inf
for _ in range(args.epochs):
    t0 = time.perf_counter()
    epoch()
    best_epoch = min(best_epoch, time.perf_counter() - t0)
print("torch_epoch_ms_t%d %.2f" % (args.threads, best_epoch * 1000))

if args.offspring:
    theta = x[: args.parents]
    std = math.sqrt(args.sigma)  # the reference uses sigma as a variance: xi ~ N(0, sigma I_P)
    try:
        from torch.func import jacfwd, vmap  # PyTorch >= 2.0
        method = "torch.func.vmap(jacfwd)"
    except ImportError:
        try:
            from functorch import jacfwd, vmap  # PyTorch 1.13 ships it as functorch
            method = "functorch.vmap(jacfwd)"
        except ImportError:
            jacfwd = vmap = None
            method = "loop of autograd.functional.jacobian(vectorize=True)"
    if vmap is not None:
        def jacobians(z):
            return vmap(jacfwd(model.decode))(z)
    else:
        def jacobians(z):
            return torch.stack([torch.autograd.functional.jacobian(model.decode, z[i], vectorize=True)
                                for i in range(z.shape[0])])
    print("torch_offspring_method", method)
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        with torch.no_grad():
            z = model.encode(theta)
        jac = jacobians(z)  # parents x P x LD
        xi = torch.randn(args.parents, args.p) * std
        with torch.no_grad():
            z2 = z + torch.einsum("npl,np->nl", jac, xi)
            child = model.decode(z2)
        best = min(best, (time.perf_counter() - t0) * 1000)
    print("torch_offspring_ms %.3f" % best)
