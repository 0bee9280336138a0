"""Parallel loops over signal-size arrays (numba): the memory passes between a reconstruction's FFTs.

Between its FFTs a CoSaMP iteration (:class:`~sparselt.operators.partial_fourier.PartialFourier`)
moves signal-size data four ways: it zeroes the spectrum buffer that the
inverse FFT destroyed, gathers the grid at the sampled cells, scatters the
residual into the grid and forms the proxy's energy ``|A^* r|^2`` on every
coefficient; after recovery the inverse gamma raises the whole grid to
``1 / gamma``. NumPy does each on one core, ``np.square`` allocates (and
page-faults) a new signal-size array per call, and ``np.power`` takes a slow
path for every zero (half of a clamped reconstruction). On 250x250x16x16
these passes cost as much as half the FFTs' time (issue 24's profile). Each
loop here runs on every core into a buffer the caller owns and computes
exactly what the NumPy expression computes (the same float operations, no
fast-math; the power itself is still NumPy's), so results are bit-identical.

The same holds for the other hot loops issue 24's profiles found: the slot
table of the SFT's sample caches (:class:`~sparselt.recovery.sample_cache.IndexedValues`:
numbering, lookups, row gathers), the cell means of pixel samples summed per
image-cell block (bincount's sums without its grid-size arrays), and the
global guided mode's counting sort of lanes by film pixel and its splat in
lane order (the same bytes for the same seed).

Kernels compile on first use and are cached on disk by numba; :func:`warm_up`
compiles them all (the comparison's warm-up calls it, so that no timed run
pays compilation).
"""

from __future__ import annotations

import numpy as np

_KERNELS = None

#: Below this many elements a loop stays in NumPy (thread start-up would cost more than it saves).
PARALLEL_MINIMUM = 1 << 16


def _compiled():
    """The numba kernels, compiled on first use (and cached on disk by numba)."""
    global _KERNELS
    if _KERNELS is None:
        import numba

        @numba.njit(parallel=True, cache=True)
        def gather(source, indices, out):
            for position in numba.prange(indices.size):
                out[position] = source[indices[position]]

        @numba.njit(parallel=True, cache=True)
        def scatter(target, indices, values):
            for position in numba.prange(indices.size):
                target[indices[position]] = values[position]

        @numba.njit(parallel=True, cache=True)
        def zero(array):
            for position in numba.prange(array.size):
                array[position] = 0

        @numba.njit(parallel=True, cache=True)
        def squared_magnitude(real, imaginary, out):
            for position in numba.prange(out.size):
                out[position] = real[position] * real[position] + imaginary[position] * imaginary[position]

        @numba.njit(parallel=True, cache=True)
        def mark_non_positive(values, marks):
            for position in numba.prange(values.size):
                value = values[position]
                marked = value <= 0
                marks[position] = marked
                values[position] = 1 if marked else value

        @numba.njit(parallel=True, cache=True)
        def zero_marked(values, marks):
            for position in numba.prange(values.size):
                values[position] = 0 if marks[position] else values[position]

        @numba.njit(cache=True)
        def counting_order(keys, bins):
            starts = np.zeros(bins + 1, dtype=np.int64)
            for key in keys:
                starts[key + 1] += 1
            for position in range(bins):
                starts[position + 1] += starts[position]
            order = np.empty(keys.size, dtype=np.uint32)
            for position in range(keys.size):
                key = keys[position]
                order[starts[key]] = position
                starts[key] += 1
            return order

        @numba.njit(parallel=True, cache=True)
        def number_slots(slots, indices, first):
            for position in numba.prange(indices.size):
                slots[indices[position]] = first + position + 1

        @numba.njit(parallel=True, cache=True)
        def gather_slotted(values, slots, indices, out):
            for position in numba.prange(indices.size):
                row = slots[indices[position]] - 1
                for column in range(values.shape[1]):
                    out[position, column] = values[row, column]

        @numba.njit(cache=True)
        def unnumbered(slots, indices):
            out = np.empty(indices.size, dtype=np.int64)
            count = 0
            for position in range(indices.size):
                index = indices[position]
                if slots[index] == 0:
                    out[count] = index
                    count += 1
            return out[:count]

        @numba.njit(parallel=True, cache=True)
        def merge_runs(result, column, partial, rows, starts, operation):
            for run in numba.prange(rows.size):
                row = rows[run]
                value = result[row, column]
                for position in range(starts[run], starts[run + 1]):
                    if operation == 0:
                        value += np.float64(partial[position])
                    elif operation == 1:
                        value = min(value, np.float64(partial[position]))
                    else:
                        value = max(value, np.float64(partial[position]))
                result[row, column] = value

        @numba.njit(parallel=True, cache=True)
        def block_sums(cells, weights, spp, width, upscale_x, upscale_y, grid_height, block_cells, per_block,
                       out_cells, out_sums, out_counts, filled, stray):
            blocks = filled.size
            for block in numba.prange(blocks):
                grid_x, grid_y = block // grid_height, block % grid_height
                base = block * block_cells
                counts = np.zeros(block_cells, dtype=np.int64)
                sums = np.zeros(block_cells, dtype=np.float64)
                for pixel_y in range(grid_y * upscale_y, (grid_y + 1) * upscale_y):  # increasing pixel index:
                    for pixel_x in range(grid_x * upscale_x, (grid_x + 1) * upscale_x):  # bincount's order
                        pixel = pixel_y * width + pixel_x
                        for row in range(pixel * spp, (pixel + 1) * spp):
                            cell = cells[row] - base
                            if cell < 0 or cell >= block_cells:
                                stray[row] = True
                            else:
                                counts[cell] += 1
                                sums[cell] += weights[row]
                offset = block * per_block
                kept = 0
                for cell in range(block_cells):
                    if counts[cell]:
                        out_cells[offset + kept] = base + cell
                        out_sums[offset + kept] = sums[cell]
                        out_counts[offset + kept] = counts[cell]
                        kept += 1
                filled[block] = kept

        @numba.njit(parallel=True, cache=True)
        def run_ramps(starts, counts, bases, step, out):
            for run in numba.prange(starts.size):
                start, base = starts[run], bases[run]
                for position in range(counts[run]):
                    out[start + position] = base + step * position

        @numba.njit(cache=True)
        def ordered_sums(targets, first, second, third, out):
            for lane in range(targets.size):
                target = targets[lane]
                out[target, 0] += first[lane]
                out[target, 1] += second[lane]
                out[target, 2] += third[lane]

        @numba.njit(inline="always")
        def soft(value, threshold):
            sign = 1.0 if value > 0 else (-1.0 if value < 0 else 0.0)
            magnitude = abs(value) - threshold
            return sign * max(0.0, magnitude)

        @numba.njit(parallel=True, cache=True)
        def admm_right_hand_side(targets, z, u, alpha, out):
            b0, b1, b2 = targets
            z0, z1, z2 = z
            u0, u1, u2 = u
            height, width, channels = out.shape
            for y in numba.prange(height):
                for x in range(width):
                    for c in range(channels):
                        value = 0.0
                        if x < width - 1:
                            value = value - ((b1[y, x, c] + z1[y, x, c]) - u1[y, x, c])
                        if x >= 1:
                            value = value + ((b1[y, x - 1, c] + z1[y, x - 1, c]) - u1[y, x - 1, c])
                        if y < height - 1:
                            value = value - ((b2[y, x, c] + z2[y, x, c]) - u2[y, x, c])
                        if y >= 1:
                            value = value + ((b2[y - 1, x, c] + z2[y - 1, x, c]) - u2[y - 1, x, c])
                        out[y, x, c] = alpha * ((b0[y, x, c] + z0[y, x, c]) - u0[y, x, c]) + value

        @numba.njit(parallel=True, cache=True)
        def admm_update(image, previous, targets, z, u, alpha, threshold):
            b0, b1, b2 = targets
            z0, z1, z2 = z
            u0, u1, u2 = u
            height, width, channels = image.shape
            change = 0.0
            norm = 0.0
            for y in numba.prange(height):
                for x in range(width):
                    for c in range(channels):
                        value = image[y, x, c]
                        step = value - previous[y, x, c]
                        change += step * step
                        norm += value * value
                        fitted = alpha * value
                        residual = (fitted - b0[y, x, c]) + u0[y, x, c]
                        shrunk = soft(residual, threshold)
                        z0[y, x, c] = shrunk
                        u0[y, x, c] = ((u0[y, x, c] + fitted) - b0[y, x, c]) - shrunk
                        if x < width - 1:
                            fitted = image[y, x + 1, c] - value
                            residual = (fitted - b1[y, x, c]) + u1[y, x, c]
                            shrunk = soft(residual, threshold)
                            z1[y, x, c] = shrunk
                            u1[y, x, c] = ((u1[y, x, c] + fitted) - b1[y, x, c]) - shrunk
                        if y < height - 1:
                            fitted = image[y + 1, x, c] - value
                            residual = (fitted - b2[y, x, c]) + u2[y, x, c]
                            shrunk = soft(residual, threshold)
                            z2[y, x, c] = shrunk
                            u2[y, x, c] = ((u2[y, x, c] + fitted) - b2[y, x, c]) - shrunk
            return change, norm

        @numba.njit(parallel=True, cache=True)
        def admm_relaxed_update(image, previous, targets, z, u, alpha, threshold, relaxation):
            b0, b1, b2 = targets
            z0, z1, z2 = z
            u0, u1, u2 = u
            height, width, channels = image.shape
            keep = 1.0 - relaxation
            change = 0.0
            norm = 0.0
            for y in numba.prange(height):
                for x in range(width):
                    for c in range(channels):
                        value = float(image[y, x, c])
                        step = value - previous[y, x, c]
                        change += step * step
                        norm += value * value
                        # soft(r, t) = r - clip(r, -t, t): the new u is the clipped residual, z the rest.
                        target = float(b0[y, x, c])
                        residual = relaxation * (alpha * value) + keep * (z0[y, x, c] + target) - target + u0[y, x, c]
                        clipped = min(max(residual, -threshold), threshold)
                        z0[y, x, c] = residual - clipped
                        u0[y, x, c] = clipped
                        if x < width - 1:
                            target = float(b1[y, x, c])
                            residual = (relaxation * (image[y, x + 1, c] - value) + keep * (z1[y, x, c] + target)
                                        - target + u1[y, x, c])
                            clipped = min(max(residual, -threshold), threshold)
                            z1[y, x, c] = residual - clipped
                            u1[y, x, c] = clipped
                        if y < height - 1:
                            target = float(b2[y, x, c])
                            residual = (relaxation * (image[y + 1, x, c] - value) + keep * (z2[y, x, c] + target)
                                        - target + u2[y, x, c])
                            clipped = min(max(residual, -threshold), threshold)
                            z2[y, x, c] = residual - clipped
                            u2[y, x, c] = clipped
            return change, norm

        @numba.njit(parallel=True, cache=True)
        def screened_spectrum(primal_spectrum, gradient_spectrum, eigenvalues, weight, out):
            height, width, channels = out.shape
            for y in numba.prange(height):
                for x in range(width):
                    denominator = weight + eigenvalues[y, x, 0]
                    for c in range(channels):
                        out[y, x, c] = (primal_spectrum[y, x, c] * weight + gradient_spectrum[y, x, c]) / denominator

        @numba.njit(parallel=True, cache=True)
        def held_out_terms(first, first_judge, second, second_judge, weights, out):
            height, width, channels = first.shape
            for y in numba.prange(height):
                for x in range(width):
                    total = 0.0
                    for c in range(channels):
                        step = float(first[y, x, c]) - float(first_judge[y, x, c])
                        other = float(second[y, x, c]) - float(second_judge[y, x, c])
                        total += step * step + other * other
                    out[y, x] = weights[y, x] * total

        @numba.njit(parallel=True, cache=True)
        def replay_estimates(sums, emission, subtract, shift_x, shift_y, spp, primal, gradient_x, gradient_y):
            height, width, paths, channels = sums.shape
            count_x = 0
            count_y = 0
            for k in range(1, paths):
                if shift_x[k - 1] != 0:
                    count_x += 1
                else:
                    count_y += 1
            for y in numba.prange(height):
                for x in range(width):
                    landed = 1.0
                    for k in range(1, paths):
                        if 0 <= x - shift_x[k - 1] < width and 0 <= y - shift_y[k - 1] < height:
                            landed += 1.0
                    for c in range(channels):
                        value = float(sums[y, x, 0, c])
                        if subtract:
                            value -= emission[y, x, 0, c]
                        # Each neighbour's offset that lands here, in shift order (NumPy's order of additions).
                        for k in range(1, paths):
                            source_x = x - shift_x[k - 1]
                            source_y = y - shift_y[k - 1]
                            if 0 <= source_x < width and 0 <= source_y < height:
                                offset = float(sums[source_y, source_x, k, c])
                                if subtract:
                                    offset -= emission[source_y, source_x, k, c]
                                value += offset
                        primal[y, x, c] = value / (spp * landed)
                        # The difference to the next pixel along x (then y): each pair that spans the two, in order.
                        for axis in range(2):
                            if (axis == 0 and x == width - 1) or (axis == 1 and y == height - 1):
                                continue
                            total = 0.0
                            for k in range(1, paths):
                                step_x = shift_x[k - 1]
                                step_y = shift_y[k - 1]
                                if (step_x != 0) != (axis == 0):
                                    continue
                                base_x = x + (1 if step_x < 0 else 0)
                                base_y = y + (1 if step_y < 0 else 0)
                                offset = float(sums[base_y, base_x, k, c])
                                base = float(sums[base_y, base_x, 0, c])
                                if subtract:
                                    offset -= emission[base_y, base_x, k, c]
                                    base -= emission[base_y, base_x, 0, c]
                                if step_x + step_y > 0:
                                    total += offset
                                    total -= base
                                else:
                                    total -= offset
                                    total += base
                            if axis == 0:
                                gradient_x[y, x, c] = total / (spp * count_x)
                            else:
                                gradient_y[y, x, c] = total / (spp * count_y)

        _KERNELS = {"held_out_terms": held_out_terms, "screened_spectrum": screened_spectrum, "run_ramps": run_ramps, "replay_estimates": replay_estimates, "admm_right_hand_side": admm_right_hand_side, "admm_update": admm_update,
                    "admm_relaxed_update": admm_relaxed_update, "gather": gather, "scatter": scatter, "zero": zero, "squared_magnitude": squared_magnitude,
                    "mark_non_positive": mark_non_positive, "zero_marked": zero_marked,
                    "number_slots": number_slots, "gather_slotted": gather_slotted, "unnumbered": unnumbered,
                    "block_sums": block_sums, "counting_order": counting_order, "ordered_sums": ordered_sums,
                    "merge_runs": merge_runs}
    return _KERNELS


def gather(source, indices, out):
    """``out[:] = source[indices]`` for flat arrays; returns ``out``."""
    if indices.size < PARALLEL_MINIMUM:
        np.take(source, indices, out=out)
    else:
        _compiled()["gather"](source, indices, out)
    return out


def scatter(target, indices, values):
    """``target[indices] = values`` for a flat ``target`` and distinct ``indices``."""
    if indices.size < PARALLEL_MINIMUM:
        target[indices] = values
    else:
        _compiled()["scatter"](target, indices, values)


def zero(array):
    """``array.fill(0)`` for a contiguous array, on every core."""
    flat = array.reshape(-1)
    if np.iscomplexobj(flat):
        flat = flat.view(flat.real.dtype)
    if flat.size < PARALLEL_MINIMUM:
        flat.fill(0)
    else:
        _compiled()["zero"](flat)


def squared_magnitude(spectrum, out):
    """``out[:] = spectrum.real ** 2 + spectrum.imag ** 2`` (each rounded as NumPy rounds it); returns ``out``.

    ``spectrum`` is a contiguous complex array, ``out`` a contiguous real array
    of its size and precision.
    """
    flat = spectrum.reshape(-1)
    target = out.reshape(-1)
    if flat.size < PARALLEL_MINIMUM:
        np.square(flat.real, out=target)
        target += np.square(flat.imag)
    else:
        _compiled()["squared_magnitude"](flat.real, flat.imag, target)
    return out


def number_slots(slots, indices, first):
    """``slots[indices] = first + 1 + arange(len(indices))``: numbering new entries of a slot table.

    The table of :class:`~sparselt.recovery.sample_cache.IndexedValues` (0 = not read, else position + 1).
    """
    if indices.size < PARALLEL_MINIMUM:
        slots[indices] = np.arange(first + 1, first + 1 + indices.size)
    else:
        _compiled()["number_slots"](slots, indices, first)


def gather_slotted(values, slots, indices):
    """``values[slots[indices] - 1]`` (rows of ``values``) in one pass, on every core."""
    out = np.empty((indices.size,) + values.shape[1:], dtype=values.dtype)
    if indices.size < PARALLEL_MINIMUM:
        np.take(values, slots[indices] - 1, axis=0, out=out)
    else:
        _compiled()["gather_slotted"](values.reshape(values.shape[0], -1), slots, indices,
                                      out.reshape(indices.size, -1))
    return out


def unnumbered(slots, indices):
    """The entries of ``indices`` (in their order) whose slot is 0: ``indices[slots[indices] == 0]``."""
    if indices.size < PARALLEL_MINIMUM:
        return indices[slots[indices] == 0]
    return _compiled()["unnumbered"](slots, indices)


def pixel_block_cell_sums(cells, weights, spp, resolution, grid_shape):
    """Per-cell sample counts and weight sums of pixel samples, summed as ``numpy.bincount`` sums them.

    ``cells`` and ``weights`` hold ``spp`` samples per output pixel, pixel-major
    in row-major pixel order (:class:`~sparselt.methods.pixel_samples.PixelSamples`);
    a pixel's samples lie in the block of cells of the grid image cell
    over it (C order, image axes first). Each block is summed by one thread
    in increasing sample order, as bincount sums, without the grid-size
    count and sum arrays bincount fills and scans. A sample whose jitter
    rounded into the neighbouring cell (a few in a million) strays from its
    block: the cells strays reach are summed again over all their samples in
    sample order. Returns ``(cells, sums, counts)`` of the cells with
    samples, sorted, sums in float64.
    """
    width, height = resolution
    upscale_x, upscale_y = width // grid_shape[0], height // grid_shape[1]
    block_cells = 1
    for size in grid_shape[2:]:
        block_cells *= int(size)
    blocks = int(grid_shape[0]) * int(grid_shape[1])
    per_block = min(block_cells, upscale_x * upscale_y * spp)
    out_cells = np.empty(blocks * per_block, dtype=np.int64)
    out_sums = np.empty(blocks * per_block, dtype=np.float64)
    out_counts = np.empty(blocks * per_block, dtype=np.int64)
    filled = np.empty(blocks, dtype=np.int64)
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    weights = np.ascontiguousarray(weights)
    stray = np.zeros(cells.size, dtype=np.bool_)
    _compiled()["block_sums"](cells, weights, int(spp), int(width), int(upscale_x), int(upscale_y), int(grid_shape[1]),
                              int(block_cells), int(per_block), out_cells, out_sums, out_counts, filled, stray)
    keep = (np.arange(per_block)[None, :] < filled[:, None]).reshape(-1)
    found, sums, counts = out_cells[keep], out_sums[keep], out_counts[keep]
    stray_rows = np.flatnonzero(stray)
    if stray_rows.size == 0:
        return found, sums, counts
    # The cells strays reach: every sample of each, in sample order (its own block's rows and the strays).
    reached = np.unique(cells[stray_rows])
    totals, numbers = np.empty(reached.size), np.empty(reached.size, dtype=np.int64)
    for position, cell in enumerate(reached):
        block = int(cell) // block_cells
        grid_x, grid_y = divmod(block, int(grid_shape[1]))
        pixel_y, pixel_x = np.meshgrid(np.arange(grid_y * upscale_y, (grid_y + 1) * upscale_y),
                                       np.arange(grid_x * upscale_x, (grid_x + 1) * upscale_x), indexing="ij")
        pixels = (pixel_y * width + pixel_x).reshape(-1)
        rows = np.concatenate([(pixels[:, None] * spp + np.arange(spp)[None, :]).reshape(-1), stray_rows])
        rows = np.sort(rows[cells[rows] == cell])
        total = 0.0
        for row in rows:  # sequential float64 additions in sample order: bincount's sum
            total += float(weights[row])
        totals[position], numbers[position] = total, rows.size
    where = np.searchsorted(found, reached)
    present = where < found.size
    present[present] = found[where[present]] == reached[present]
    sums[where[present]], counts[where[present]] = totals[present], numbers[present]
    if present.all():
        return found, sums, counts
    insert = np.searchsorted(found, reached[~present])
    return (np.insert(found, insert, reached[~present]), np.insert(sums, insert, totals[~present]),
            np.insert(counts, insert, numbers[~present]))


def run_ramps(counts, bases, step, dtype):
    """Runs laid end to end: run ``k`` is ``counts[k]`` values ``bases[k], bases[k] + step, ...``; on every core.

    ``np.repeat(bases, counts) + step * (np.arange(n) - np.repeat(starts, counts))``
    (``starts`` each run's first position, ``n`` the total) without its
    lane-size temporaries: ``step`` 0 repeats each base (a lane's pixel),
    1 numbers a run's lanes from its base (sample indices, slots). Integer
    ``dtype`` (the values must fit it). Returns the new array.
    """
    counts = np.ascontiguousarray(counts, dtype=np.int64)
    bases = np.ascontiguousarray(bases, dtype=np.int64)
    if counts.shape != bases.shape or counts.ndim != 1:
        raise ValueError(f"counts and bases must be one-dimensional and of one length, got {counts.shape} and "
                         f"{bases.shape}")
    if counts.size and counts.min() < 0:
        raise ValueError("run counts must not be negative")
    starts = np.cumsum(counts) - counts
    out = np.empty(int(counts.sum()), dtype=dtype)
    if out.size < PARALLEL_MINIMUM:
        out[:] = np.repeat(bases, counts) + step * (np.arange(out.size) - np.repeat(starts, counts))
    else:
        _compiled()["run_ramps"](starts, counts, bases, int(step), out)
    return out


def ordered_sums(targets, channels, bins):
    """Per-bin sums of three channels, each added in lane order: a splat whose result does not depend on threads.

    ``targets`` (uint32) and the three ``channels`` (float32) have one entry
    per lane; returns a float32 array ``(bins, 3)``.
    """
    targets = np.ascontiguousarray(targets, dtype=np.uint32)
    if targets.size and int(targets.max()) >= bins:
        raise ValueError(f"targets must be below bins={bins}, got {int(targets.max())}")
    out = np.zeros((int(bins), 3), dtype=np.float32)
    first, second, third = (np.ascontiguousarray(channel, dtype=np.float32) for channel in channels)
    _compiled()["ordered_sums"](targets, first, second, third, out)
    return out


#: The reductions :func:`merge_runs` applies, by name (as :data:`~sparselt.rendering.mitsuba.PIXEL_STATISTICS`).
MERGE_OPERATIONS = {"sum": 0, "min": 1, "max": 2}


def merge_runs(result, partial, rows, starts, reduction):
    """Merge per-block reductions into per-row ones, in place: each row's blocks one after another, in order.

    ``result`` is float64 ``(rows,)`` or ``(rows, k)``; ``partial`` one
    float32 array per column of ``result`` (a sequence), one value per
    block; the blocks come in runs, run ``j`` being blocks ``starts[j] ..
    starts[j + 1] - 1`` of row ``rows[j]`` (``starts`` has one more entry
    than ``rows``; each row in one run). ``reduction`` is one of
    :data:`MERGE_OPERATIONS`: the row's value is summed with (or takes the
    minimum or maximum of) each of its blocks in order, widened to float64,
    so the result does not depend on threads; runs go to every core.
    """
    operation = MERGE_OPERATIONS[reduction]
    table = result.reshape(result.shape[0], -1)
    if table.shape[1] != len(partial) or not np.shares_memory(table, result) or table.dtype != np.float64:
        raise ValueError(f"result must be a contiguous (rows, {len(partial)}) float64 array, got shape "
                         f"{result.shape} of {result.dtype}")
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    if starts.size != rows.size + 1:
        raise ValueError(f"starts must have one entry more than rows, got {starts.size} and {rows.size}")
    for column, values in enumerate(partial):
        values = np.ascontiguousarray(values, dtype=np.float32)
        if values.size != starts[-1]:
            raise ValueError(f"each column of partial must have {starts[-1]} blocks, got {values.size}")
        _compiled()["merge_runs"](table, column, values, rows, starts, operation)


def counting_order(keys, bins):
    """The stable order that sorts ``keys`` (uint32, each below ``bins``): a counting sort, two passes.

    Returns a uint32 permutation ``order`` with ``keys[order]`` non-decreasing
    and equal keys in their original order (``numpy.argsort(keys,
    kind='stable')``, about 20x faster on 16M keys).
    """
    keys = np.ascontiguousarray(keys, dtype=np.uint32)
    if keys.size >= 1 << 32:
        raise ValueError(f"counting_order numbers positions in uint32; got {keys.size} keys")
    if keys.size and int(keys.max()) >= bins:
        raise ValueError(f"keys must be below bins={bins}, got {int(keys.max())}")
    return _compiled()["counting_order"](keys, int(bins))


def clamped_power(values, exponent):
    """``values[:] = np.maximum(values, 0) ** exponent`` in place, for a positive ``exponent``; returns ``values``.

    The inverse gamma of eq. 7.1 (thesis 7.1) on a reconstruction. Entries
    ``<= 0`` are set to 1 before NumPy's power and to 0 after it, which is
    what the power gives them; NaN stays NaN. The power of every other entry
    is NumPy's own, so the result is bit-identical to the expression's.
    """
    flat = values.reshape(-1)
    exponent = flat.dtype.type(exponent)
    if not exponent > 0:
        raise ValueError(f"exponent must be positive, got {exponent}")
    if flat.size < PARALLEL_MINIMUM:
        np.maximum(flat, 0, out=flat)
        np.power(flat, exponent, out=flat)
        return values
    kernels = _compiled()
    marks = np.empty(flat.size, dtype=np.bool_)
    kernels["mark_non_positive"](flat, marks)
    np.power(flat, exponent, out=flat)
    kernels["zero_marked"](flat, marks)
    return values


def admm_right_hand_side(targets, z, u, alpha, out):
    """``out = alpha s_0 + D_x^T s_1 + D_y^T s_2`` with ``s_k = (b_k + z_k) - u_k``: one pass, on every core.

    The right-hand side of the ``I`` step of
    :func:`~sparselt.recovery.poisson.screened_poisson_l1`'s ADMM, the same
    float operations in the same order as ``alpha * shifted[0] +
    difference_adjoint(shifted[1], shifted[2])``, so bit-identical to it.
    ``targets``, ``z``, ``u``: triples of float64 arrays shaped ``(height,
    width, channels)``, ``(height, width - 1, channels)`` and ``(height - 1,
    width, channels)``; ``out`` ``(height, width, channels)``. Returns ``out``.
    """
    _compiled()["admm_right_hand_side"](tuple(targets), tuple(z), tuple(u), float(alpha), out)
    return out


def admm_update(image, previous, targets, z, u, alpha, threshold):
    """The ``z`` and ``u`` steps of the ADMM after an ``I`` step, in place, in one pass on every core.

    For each of ``H I = (alpha I, D_x I, D_y I)``'s parts: ``z_k =
    soft(H_k I - b_k + u_k, threshold)`` then ``u_k = u_k + H_k I - b_k -
    z_k``, each as :func:`~sparselt.recovery.poisson.screened_poisson_l1`'s
    NumPy expressions evaluate it (bit-identical). Returns ``(|I -
    previous|^2, |I|^2)``, the stop rule's sums (summed in another order
    than NumPy's norm: equal to rounding).
    """
    return _compiled()["admm_update"](image, previous, tuple(targets), tuple(z), tuple(u), float(alpha),
                                      float(threshold))


def admm_relaxed_update(image, previous, targets, z, u, alpha, threshold, relaxation):
    """The over-relaxed ``z`` and ``u`` steps of the ADMM after an ``I`` step, in place, in one pass on every core.

    For each of ``H I = (alpha I, D_x I, D_y I)``'s parts, with ``r`` the
    relaxation (Boyd et al. 2011, 3.4.3): ``h_k = r H_k I + (1 - r) (z_k +
    b_k)``, ``z_k = soft(h_k - b_k + u_k, threshold)``, ``u_k = h_k - b_k +
    u_k - z_k``, computed branch-free as ``u_k = clip(h_k - b_k + u_k,
    -threshold, threshold)``, ``z_k = (h_k - b_k + u_k) - u_k`` (the same
    values, not the same roundings as :func:`admm_update`). Arithmetic in float64 whatever the arrays' precision (float32
    or float64; each loop's order fixed, so the same inputs give the same
    bytes). Returns ``(|I - previous|^2, |I|^2)`` in float64 (the stop rule's sums).

    References
    ----------
    Boyd, S., Parikh, N., Chu, E., Peleato, B., Eckstein, J. (2011).
    Distributed optimization and statistical learning via the alternating
    direction method of multipliers. Foundations and Trends in Machine
    Learning 3(1), section 3.4.3.
    """
    return _compiled()["admm_relaxed_update"](image, previous, tuple(targets), tuple(z), tuple(u), float(alpha),
                                              float(threshold), float(relaxation))


def screened_spectrum(primal_spectrum, gradient_spectrum, eigenvalues, weight, out):
    """``out = (primal_spectrum * weight + gradient_spectrum) / (weight + eigenvalues)``: one pass, on every core.

    The spectrum of the screened Poisson solution at ``weight = alpha^2``
    (:func:`~sparselt.recovery.poisson.screened_poisson_family`): the two
    spectra and ``out`` are float32 ``(height, width, channels)``, the
    eigenvalues float32 ``(height, width, 1)``; the same float32 operations
    in the same order as NumPy's ``np.multiply``, ``+=`` and ``/=`` on those
    arrays, so bit-identical to them. Returns ``out``.
    """
    _compiled()["screened_spectrum"](primal_spectrum, gradient_spectrum, eigenvalues, np.float32(weight), out)
    return out


def held_out_terms(first, first_judge, second, second_judge, weights):
    """A held-out score's per-pixel terms ``w * sum over channels of ((A - J_A)^2 + (B - J_B)^2)``, on every core.

    ``first``, ``second`` (two reconstructions) and their judges share one
    shape ``(height, width, ...)``, float32 or float64; ``weights`` is
    ``(height, width)`` or ``(height, width, 1)``. The differences and sums
    are float64. Returns a new float64 array ``(height, width, 1)`` (the
    terms of :func:`~sparselt.recovery.poisson.held_out_choice` and
    :func:`~sparselt.recovery.poisson.held_out_l1_check`; their NumPy
    expressions, summed over channels in another order: equal to rounding).
    """
    height, width = first.shape[:2]

    def flat(array):
        array = np.asarray(array)
        if array.dtype not in (np.float32, np.float64):
            array = array.astype(np.float64)
        return np.ascontiguousarray(array).reshape(height, width, -1)

    out = np.empty((height, width), dtype=np.float64)
    _compiled()["held_out_terms"](flat(first), flat(first_judge), flat(second), flat(second_judge),
                                  np.ascontiguousarray(weights, dtype=np.float64).reshape(height, width), out)
    return out.reshape(height, width, 1)


def replay_estimates(sums, shifts, spp, emission=None):
    """The primal and gradient images of the replay shift's per-path sums, on every core.

    What :func:`sparselt.methods.gradient_domain.gradient_estimates`
    computes without ``pairs`` (Kettunen et al. 2015, 3: every path that
    lands in a pixel estimates it; each base/offset pair that spans two
    pixels estimates their difference), in one pass instead of NumPy's
    shifted slices and temporaries, with ``sums - emission`` formed where
    read. The additions happen in NumPy's order (each path's sums in shift
    order, float64), so the result is bit-identical to it.

    Parameters
    ----------
    sums : ndarray, shape (height, width, 1 + offsets, 3), float32 or float64
        Base paths at index 0, the offsets of ``shifts`` after.
    shifts : sequence of (dx, dy)
        Each offset's shift (unit steps along one axis).
    spp : int
        Base samples per pixel.
    emission : ndarray, same shape, optional
        Subtracted from ``sums`` (the emission seen directly, estimated apart).

    Returns
    -------
    primal : ndarray (height, width, 3); gradient_x : (height, width - 1, 3); gradient_y : (height - 1, width, 3)
        float64.
    """
    sums = np.ascontiguousarray(sums)
    if sums.dtype not in (np.float32, np.float64):
        sums = sums.astype(np.float64)
    height, width, _, channels = sums.shape
    subtract = emission is not None
    emission = np.ascontiguousarray(emission, dtype=np.float64) if subtract else np.zeros((1, 1, 1, 1))
    shift_x = np.array([dx for dx, _ in shifts], dtype=np.int64)
    shift_y = np.array([dy for _, dy in shifts], dtype=np.int64)
    primal = np.empty((height, width, channels))
    gradient_x = np.empty((height, max(0, width - 1), channels))
    gradient_y = np.empty((max(0, height - 1), width, channels))
    _compiled()["replay_estimates"](sums, emission, subtract, shift_x, shift_y, int(spp), primal, gradient_x,
                                    gradient_y)
    return primal, gradient_x, gradient_y


_WARM = False


def warm_up():
    """Compile (or load from numba's cache) every kernel for the types sparselt uses; free after the first call."""
    global _WARM
    if _WARM:
        return
    size = PARALLEL_MINIMUM
    kernels = _compiled()
    indices = np.arange(size, dtype=np.int64)
    for real, complex_ in ((np.float32, np.complex64), (np.float64, np.complex128)):
        source = np.zeros(size, dtype=real)
        out = np.empty(size, dtype=real)
        kernels["gather"](source, indices, out)
        kernels["scatter"](source, indices, out)
        kernels["zero"](source)
        spectrum = np.zeros(size, dtype=complex_)
        kernels["squared_magnitude"](spectrum.real, spectrum.imag, out)
        marks = np.empty(size, dtype=np.bool_)
        kernels["mark_non_positive"](out, marks)
        kernels["zero_marked"](out, marks)
    kernels["counting_order"](np.zeros(4, dtype=np.uint32), 4)
    for columns in (1, 3):
        merge_runs(np.zeros((4, columns)), [np.zeros(2, dtype=np.float32)] * columns, np.arange(2), np.arange(3),
                   "sum")
    parts = [np.zeros((3, 3, 1)), np.zeros((3, 2, 1)), np.zeros((2, 3, 1))]
    admm_right_hand_side(parts, [part.copy() for part in parts], [part.copy() for part in parts], 1.0,
                         np.empty((3, 3, 1)))
    admm_update(np.zeros((3, 3, 1)), np.zeros((3, 3, 1)), parts, [part.copy() for part in parts],
                [part.copy() for part in parts], 1.0, 1.0)
    for real in (np.float32, np.float64):  # the L1 solve's I step in single precision (its default) and double
        admm_right_hand_side(parts, [part.copy() for part in parts], [part.copy() for part in parts], 1.0,
                             np.empty((3, 3, 1), dtype=real))
        admm_relaxed_update(np.zeros((3, 3, 1), dtype=real), np.zeros((3, 3, 1), dtype=real), parts,
                            [part.copy() for part in parts], [part.copy() for part in parts], 1.0, 1.0, 1.6)
    for dtype in (np.uint32, np.int64):  # the allocated lanes' pixels and sample indices, their slots
        kernels["run_ramps"](np.zeros(1, dtype=np.int64), np.ones(1, dtype=np.int64), np.zeros(1, dtype=np.int64), 1,
                             np.empty(1, dtype=dtype))
    ordered_sums(np.zeros(4, dtype=np.uint32), [np.zeros(4, dtype=np.float32)] * 3, 4)
    for sums in (np.float32, np.float64):  # the gradient methods' estimates, with and without emission apart
        replay_estimates(np.zeros((2, 2, 5, 3), dtype=sums), ((1, 0), (-1, 0), (0, 1), (0, -1)), 1)
        replay_estimates(np.zeros((2, 2, 5, 3), dtype=sums), ((1, 0), (-1, 0), (0, 1), (0, -1)), 1,
                         np.zeros((2, 2, 5, 3)))
    screened_spectrum(*(np.zeros((2, 2, 3), dtype=np.float32) for _ in range(2)), np.ones((2, 2, 1), dtype=np.float32),
                      1.0, np.empty((2, 2, 3), dtype=np.float32))
    for image in (np.float32, np.float64):  # the held-out scores: float32 images (the alpha family), float64 (L1)
        held_out_terms(np.zeros((2, 2, 1), dtype=image), np.zeros((2, 2, 1)), np.zeros((2, 2, 1), dtype=image),
                       np.zeros((2, 2, 1)), np.ones((2, 2)))
    for weights in (np.zeros(4, dtype=np.float32), np.zeros(4, dtype=np.float64)):
        pixel_block_cell_sums(np.zeros(4, dtype=np.int64), weights, 1, (2, 2), (2, 2, 1))
    slots = np.zeros(size, dtype=np.int32)
    kernels["number_slots"](slots, indices, 0)
    kernels["unnumbered"](slots, indices)
    for dtype, columns in ((np.float32, 3), (np.complex128, 1)):  # the path-space oracle's and the SFT's caches
        kernels["gather_slotted"](np.zeros((size, columns), dtype=dtype), slots, indices,
                                  np.empty((size, columns), dtype=dtype))
    for complex_ in (np.complex64, np.complex128):  # the complex operator's grid
        kernels["scatter"](np.zeros(size, dtype=complex_), indices, np.zeros(size, dtype=complex_))
        kernels["gather"](np.zeros(size, dtype=complex_), indices, np.empty(size, dtype=complex_))
    _WARM = True
