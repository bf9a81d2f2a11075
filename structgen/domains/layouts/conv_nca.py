"""The 2D convolutional NCA of the warehouse paper's code, grown for a whole population in one call.

One step maps a ``(tiles, H, W)`` state to a new one of the same shape: a 3x3 convolution to 32 hidden channels (zero
padding), ReLU, a 1x1 convolution 32 -> 32, ReLU, a 1x1 convolution back to one channel per tile, sigmoid. Growth
starts from the one-hot of a seed layout, feeds the continuous output back in for ``iterations`` steps, and takes the
argmax over tiles once at the end. Only the first layer sees neighbours, so the same weights grow a layout of any
size. This is the original code's network, not the paper text's (three 3x3 layers).

A genome is one flat vector in the original's order: first layer weights ``(32, tiles, 3, 3)`` then bias, second
``(32, 32)`` then bias, third ``(tiles, 32)`` then bias, each row-major: 2051 parameters for 3 tiles, 2693 for 5,
1730 for 2. On a GPU (``device="cuda"``) a population of ``P`` genomes runs as one grouped convolution and two
batched matrix products in float32; on a CPU each genome runs on its own, spread over threads, in the layout that
gives the original's own arithmetic (and layouts). A genome stops once its state has settled (``SETTLE_CHANGE``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from structgen.budget import check_memory
from structgen.devices import resolve_device
from structgen.threads import one_torch_thread

__all__ = ["ConvNCA", "parameter_count"]


#: Hidden channels of the paper's generators.
HIDDEN = 32

# When a genome's state has settled, its remaining steps cannot change the layout, and its growth stops there.
# Settled means: for SETTLE_PATIENCE steps in a row no value moved by more than SETTLE_CHANGE (a few float32 units in
# the last place near 1: the rounding noise that a converged state keeps making), and in every cell the winning tile
# leads the next by more than the remaining steps could close if each moved both values by SETTLE_CHANGE. Genomes
# near the search's start settle in 15 to 40 steps; chaotic ones never do and run every step. Full growth and
# settled growth are compared layout for layout in tests/layouts/test_layouts.py.
SETTLE_CHANGE = 4e-7
SETTLE_PATIENCE = 10
# A genome that moved by more than SETTLE_FAR is far from settled, and is looked at again only SETTLE_SKIP steps
# later: the check costs a tenth of a step at 101x102 and a quarter at 33x36, which chaotic genomes would pay always.
SETTLE_FAR = 1e-2
SETTLE_SKIP = 4
# Maps smaller than this grow on one thread: at 33x36 a step's operations are so short that a second thread only
# fought the first for Python's lock (no faster alone, 10 % slower beside a busy process, on 2 cores).
_THREADS_FROM_CELLS = 4096


def parameter_count(tiles: int, hidden: int = HIDDEN) -> int:
    """How many numbers a genome of a ``tiles``-channel NCA has."""
    return hidden * tiles * 9 + hidden + hidden * hidden + hidden + tiles * hidden + tiles


@dataclass(frozen=True)
class ConvNCA:
    """The network's shape: ``tiles`` channels in and out, ``hidden`` channels between."""

    tiles: int
    hidden: int = HIDDEN

    def __post_init__(self) -> None:
        for name in ("tiles", "hidden"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= 1024:
                raise ValueError(f"ConvNCA {name} must be an integer from 1 to 1024, got {value!r}")

    @property
    def n_params(self) -> int:
        return parameter_count(self.tiles, self.hidden)

    def unpack(self, genomes: Any) -> tuple[Any, ...]:
        """The six parameter tensors of every genome, from a ``(P, n_params)`` tensor: first layer ``(P, h, t, 3,
        3)`` and ``(P, h)``, second ``(P, h, h)`` and ``(P, h)``, third ``(P, t, h)`` and ``(P, t)``."""
        t, h = self.tiles, self.hidden
        shapes = ((h, t, 3, 3), (h,), (h, h), (h,), (t, h), (t,))
        parts, start = [], 0
        for shape in shapes:
            size = int(np.prod(shape))
            parts.append(genomes[:, start : start + size].reshape(genomes.shape[0], *shape))
            start += size
        return tuple(parts)

    def grow(
        self,
        genomes: Any,
        seeds: Any,
        iterations: int,
        device: str | None = None,
        *,
        chunk: int | None = None,
        settle: bool = True,
        return_steps: bool = False,
    ) -> Any:
        """Grow one layout per genome.

        Args:
            genomes: ``(P, n_params)`` (or one ``(n_params,)`` genome).
            seeds: the starting layout(s) as tile numbers below ``tiles``: one ``(H, W)`` for all, or ``(P, H, W)``.
            iterations: NCA steps.
            device: torch device (``"cpu"``, ``"cuda"``); None for the CPU.
            chunk: genomes per batched computation on a GPU (None: all that fit in 1 GiB); the CPU grows each
                genome on its own (spread over ``torch.get_num_threads()`` threads) whatever this says, and the
                layouts do not depend on it.
            settle: stop a genome's growth once its state has settled (see ``SETTLE_CHANGE``); False runs every
                step of every genome.
            return_steps: also return how many steps each genome ran.

        Returns:
            ``(P, H, W)`` ``uint8`` tile numbers (or ``(H, W)`` for one genome); with ``return_steps``, a pair of
            that and the ``(P,)`` steps run (or an int).
        """
        import torch

        genomes = np.asarray(genomes, dtype=np.float32)
        single = genomes.ndim == 1
        genomes = genomes[None] if single else genomes
        if genomes.ndim != 2 or genomes.shape[1] != self.n_params:
            raise ValueError(f"expected genomes of {self.n_params} numbers, got shape {genomes.shape}")
        if not np.isfinite(genomes).all():
            raise ValueError("genomes must be finite")
        seeds = np.asarray(seeds)
        if seeds.ndim == 2:
            seeds = np.broadcast_to(seeds, (genomes.shape[0], *seeds.shape))
        if seeds.ndim != 3 or seeds.shape[0] != genomes.shape[0]:
            raise ValueError(f"seeds must be (H, W) or ({genomes.shape[0]}, H, W), got shape {seeds.shape}")
        if seeds.size and (seeds.min() < 0 or seeds.max() >= self.tiles):
            raise ValueError(f"seed tiles must be from 0 to {self.tiles - 1}")
        if not isinstance(iterations, int) or iterations < 0:
            raise ValueError(f"iterations must be a non-negative integer, got {iterations!r}")
        population, height, width = seeds.shape
        per_genome = 4 * height * width * (2 * self.tiles + 2 * self.hidden)
        check_memory(per_genome, f"growing a {height} x {width} layout")
        where = resolve_device(device or "cpu")
        on_gpu = where.type != "cpu"
        out = np.empty((population, height, width), dtype=np.uint8)
        steps = np.empty(population, dtype=np.int64)
        seeds = np.asarray(seeds, dtype=np.int64)

        def grow_rows(rows: range) -> None:
            grow = self._grow_batch if on_gpu else self._grow_on_cpu
            tiles, ran = grow(torch.tensor(genomes[rows]), torch.tensor(seeds[rows]), iterations, where, settle)
            out[rows], steps[rows] = tiles.numpy(), ran.numpy()

        with torch.no_grad():
            if on_gpu:  # every genome at once, up to 1 GiB of working set
                chunk = chunk or max(1, min(population, (1 << 30) // per_genome))
                for start in range(0, population, chunk):
                    grow_rows(range(start, min(population, start + chunk)))
            else:
                self._grow_on_cores(grow_rows, population, parallel=height * width >= _THREADS_FROM_CELLS)
        if single:
            return (out[0], int(steps[0])) if return_steps else out[0]
        return (out, steps) if return_steps else out

    @staticmethod
    def _grow_on_cores(grow_rows: Any, population: int, parallel: bool = True) -> None:
        """Genomes spread over threads, each running torch on one thread of its own. Torch's own threads inside
        each small operation of a step cost more than they gave: on 2 cores, growth ran 1.5 to 3 times slower on two
        of them than on one (benchmarks/threads.py). Whole genomes per thread keep both cores busy, and a core
        taken by another process only slows its share. Results do not depend on the thread count."""
        import torch

        workers = min(population, torch.get_num_threads()) if parallel else 1
        with one_torch_thread():
            if workers <= 1:
                grow_rows(range(population))
                return
            from concurrent.futures import ThreadPoolExecutor

            def one_thread_each(rows: range) -> None:
                torch.set_num_threads(1)  # OpenMP's thread count is kept per calling thread
                with torch.no_grad():
                    grow_rows(rows)

            with ThreadPoolExecutor(workers, thread_name_prefix="structgen-grow") as pool:
                # genomes dealt out one by one (settling makes their costs uneven)
                list(pool.map(one_thread_each, (range(i, i + 1) for i in range(population))))

    def _grow_batch(self, genomes: Any, seeds: Any, iterations: int, device: Any, settle: bool = True) -> Any:
        """Growth on a GPU: every genome at once, as a grouped convolution and batched matrix products in
        ``(genome, tile, row, column)`` layout. Returns the tiles and the steps each genome ran."""
        import torch
        import torch.nn.functional as F

        genomes = genomes.to(device)
        p = genomes.shape[0]
        params = tuple(part.contiguous() for part in self.unpack(genomes))
        state = F.one_hot(seeds.to(device).long(), self.tiles).permute(0, 3, 1, 2).to(torch.float32).contiguous()
        final = torch.empty_like(state)
        steps_run = torch.full((p,), iterations, dtype=torch.int64)
        active = torch.arange(p)  # genomes still growing, as rows of the original batch
        watch = _Settling(p, iterations, tile_dim=1) if settle else None
        for step in range(iterations):
            new = self._batched_step(state, params)
            done = watch.update(step, state, new) if watch else None
            if done is not None:
                final[active[done]] = new[done.to(device)]
                steps_run[active[done]] = step + 1
                keep = ~done
                active = active[keep]
                if not len(active):
                    return final.argmax(dim=1).to(torch.uint8).cpu(), steps_run
                new = new[keep.to(device)]
                params = tuple(part[keep.to(device)] for part in params)
            state = new
        final[active] = state
        return final.argmax(dim=1).to(torch.uint8).cpu(), steps_run

    def _batched_step(self, state: Any, params: tuple[Any, ...]) -> Any:
        """One step of every genome in ``state`` ``(p, tiles, H, W)``."""
        import torch
        import torch.nn.functional as F

        w1, b1, w2, b2, w3, b3 = params
        p, _, height, width = state.shape
        hidden = F.conv2d(
            state.reshape(1, p * self.tiles, height, width),
            w1.view(p * self.hidden, self.tiles, 3, 3),
            b1.view(p * self.hidden),
            padding=1,
            groups=p,
        )
        hidden = hidden.reshape(p, self.hidden, height * width).clamp_min_(0)
        hidden2 = torch.baddbmm(b2[:, :, None], w2, hidden).clamp_min_(0)
        return torch.baddbmm(b3[:, :, None], w3, hidden2).sigmoid_().reshape(p, self.tiles, height, width)

    def _grow_on_cpu(self, genomes: Any, seeds: Any, iterations: int, device: Any, settle: bool = True) -> Any:
        """Growth on a CPU, one genome at a time with each cell's channels side by side in memory ("channels
        last"): the convolution then runs on oneDNN's fast path (measured 0.23 against 1.4 ms a step at 101x102;
        which path the default layout gets depends on strides), and the two 1x1 layers are plain matrix products
        of ``(cells, channels)`` by the weights. One genome's activations fit in cache, so batching gains nothing.
        Same results as any batch of genomes would give, by construction."""
        import torch
        import torch.nn.functional as F

        count, (height, width) = genomes.shape[0], seeds.shape[1:]
        cells = height * width
        tiles = torch.empty((count, height, width), dtype=torch.uint8)
        steps_run = torch.full((count,), iterations, dtype=torch.int64)
        hidden2 = torch.empty((cells, self.hidden))
        for index in range(count):
            w1, b1, w2, b2, w3, b3 = (part[0] for part in self.unpack(genomes[index : index + 1]))
            w1 = w1.contiguous(memory_format=torch.channels_last)
            # (cells, tiles) state, read by the convolution as a channels-last (1, tiles, H, W) view
            state = F.one_hot(seeds[index].reshape(cells), self.tiles).to(torch.float32)
            new = torch.empty_like(state)
            watch = _Settling(1, iterations, tile_dim=2) if settle else None
            for step in range(iterations):
                image = state.view(1, height, width, self.tiles).permute(0, 3, 1, 2)
                hidden = F.conv2d(image, w1, b1, padding=1).permute(0, 2, 3, 1).reshape(cells, self.hidden)
                torch.addmm(b2, hidden.clamp_min_(0), w2.T, out=hidden2).clamp_min_(0)
                torch.addmm(b3, hidden2, w3.T, out=new).sigmoid_()
                done = watch.update(step, state[None], new[None]) if watch else None
                state, new = new, state
                if done is not None:
                    steps_run[index] = step + 1
                    break
            tiles[index] = state.argmax(dim=1).to(torch.uint8).view(height, width)
        return tiles, steps_run


class _Settling:
    """Tells which genomes of a batch have settled (see ``SETTLE_CHANGE``), step by step. On a CPU the check runs in
    numpy on the tensors' memory: torch's per-call overhead made it cost half a step at 33x36."""

    def __init__(self, count: int, iterations: int, tile_dim: int) -> None:
        self.iterations, self.tile_dim = iterations, tile_dim
        self.quiet = np.zeros(count, dtype=np.int64)  # steps in a row each moved by at most SETTLE_CHANGE
        self.next_check = 0

    def update(self, step: int, old: Any, new: Any) -> Any:
        """The rows of ``new`` (one per genome still growing) that settled at this step, as a boolean tensor, or
        None if none did; the rows that did are then forgotten, as the caller drops them."""
        import torch

        if step < self.next_check:  # skipped steps count as not quiet: settling is only ever detected later
            return None
        if len(new) == 1 and new.device.type == "cpu":  # the CPU's one genome at a time: plain numbers are cheapest
            moved_one = float(np.abs(new.numpy() - old.numpy()).max())
            if moved_one > SETTLE_FAR:
                self.next_check = step + SETTLE_SKIP
            self.quiet[0] = self.quiet[0] + 1 if moved_one <= SETTLE_CHANGE else 0
            if self.quiet[0] < SETTLE_PATIENCE:
                return None
        else:
            if new.device.type == "cpu":
                moved = np.abs(new.numpy() - old.numpy()).reshape(len(new), -1).max(axis=1)
            else:
                moved = (new - old).abs_().flatten(1).amax(dim=1).cpu().numpy()
            if (moved > SETTLE_FAR).all():
                self.next_check = step + SETTLE_SKIP
            self.quiet = np.where(moved <= SETTLE_CHANGE, self.quiet + 1, 0)
        done = self.quiet >= SETTLE_PATIENCE
        if not done.any():
            return None
        rows = np.flatnonzero(done)
        top2 = new[torch.as_tensor(rows, device=new.device)].topk(2, dim=self.tile_dim).values
        lead = (top2.select(self.tile_dim, 0) - top2.select(self.tile_dim, 1)).flatten(1).amin(dim=1).cpu().numpy()
        done[rows] = lead > 2 * SETTLE_CHANGE * (self.iterations - step - 1)
        # A quiet genome whose closest cell is still too close to call is looked at again a few quiet steps later
        # (the lead it needs shrinks as the steps left do).
        self.quiet[rows[~done[rows]]] -= SETTLE_SKIP
        if not done.any():
            return None
        self.quiet = self.quiet[~done]
        return torch.as_tensor(done)
