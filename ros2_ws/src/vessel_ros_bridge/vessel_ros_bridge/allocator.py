"""
Keep a node's freed memory where its threads allocate next (glibc's malloc arenas).

glibc gives threads up to eight malloc arenas per core (16 on 2 cores) and keeps the
pages freed in each resident for its own threads. A node's executor and XLA's workers
allocate megabyte buffers from many threads (a batch's arrays, a request or an answer
in transport), so every arena ends up holding its own copy of that churn. Measured in
the predictor under the soak's load (mallinfo2, 2026-11-27): the memory in use stayed
at 100-115 MB while the free memory the arenas kept grew from 98 to 196 MB in seven
minutes (malloc_trim gave 127 MB back at once, refilled within 20 s); the resident
size looked like a leak (+10 % private memory over 30 minutes). With two arenas the
free memory kept stayed within 32-54 MB for ten minutes (private memory -0.7 %), and a
64-plan forecast was faster, not slower (median 79-86 against 96-106 ms, its blocks
reused warm). Mapping every large block on its own (a fixed mmap threshold) also held
the memory, but took 182-203 ms of CPU per 64-plan request against 163-182 ms. A
user's own setting (environment) wins; on another C library nothing is done.

Blocks of up to ``KEPT_BLOCK`` (32 MiB) are also taken from the arenas and stay there
when freed, up to ``KEPT_FREE`` (256 MiB) at the top of a heap. glibc maps a large block
on its own (above 128 kB, a threshold it raises as such blocks are freed) and gives a
heap's freed top back above 128 kB: each thousand-plan what-if answer (19 MB of
Forecasts, a copy of them serialized, the batch's arrays) was then written into fresh
pages, each a page fault the kernel zeroes. Measured in the predictor's code
(``offline/bench.py forecast``'s what-if, the snuboat's model, 1,000 plans x 100 steps,
2026-12-03): the answer written and serialized 16.9 -> 7.6 ms, the whole answer 55.5 ->
46.8 ms. The price is memory: a node keeps the high-water mark of its large answers
resident (at most ``KEPT_FREE`` free at a heap's top) instead of giving it back.

A thread keeps the arena it first allocated from, and importing numpy, rclpy or the
predictor's model starts threads (four on ``import hybrid_predictor.node``, with three
arenas): a node's console entry therefore limits them before it imports anything else
(``start_node``, from ``ship_sim_node.start`` and ``hybrid_predictor.start``), and
``run_node`` logs what was done.
"""

from __future__ import annotations

from collections.abc import Mapping
import ctypes
import importlib
import os

ARENAS = 2                      # at most, for the whole process (measured above)
KEPT_BLOCK = 32 << 20           # B: blocks up to this are the arenas', not mapped alone
KEPT_FREE = 256 << 20           # B: freed memory a heap keeps at its top
M_ARENA_MAX = -8                # mallopt's parameter numbers, <malloc.h>
M_MMAP_THRESHOLD = -3
M_TRIM_THRESHOLD = -1
_done: list[str] = []           # the note of the first call: the setting holds from then


def share_malloc_arenas(environ: Mapping[str, str] = os.environ) -> str:
    """
    Limit this process to ``ARENAS`` malloc arenas (glibc's M_ARENA_MAX).

    Return one line saying what was done, for the node's log. Call it before anything
    starts threads (module docstring); a later call returns the first one's note.
    """
    if not _done:
        _done.append(_set_malloc(environ))
    return _done[0]


def _set_malloc(environ: Mapping[str, str]) -> str:
    libc = ctypes.CDLL(None)
    if not hasattr(libc, 'gnu_get_libc_version'):
        return 'malloc: not glibc, its own arenas'
    own = user_setting(environ)
    if own:
        arenas = f'arenas set by the user ({own}), left as set'
    elif libc.mallopt(M_ARENA_MAX, ARENAS) != 1:
        arenas = 'glibc refused a limit on its arenas; one per thread as it decides'
    else:
        arenas = f'{ARENAS} arenas shared by all threads, so freed memory is reused'
    own = user_thresholds(environ)
    if own:
        kept = f'large blocks as the user set them ({own})'
    elif (libc.mallopt(M_MMAP_THRESHOLD, KEPT_BLOCK) != 1
          or libc.mallopt(M_TRIM_THRESHOLD, KEPT_FREE) != 1):
        kept = 'glibc refused to keep large blocks; each mapped and given back'
    else:
        kept = (f'blocks up to {KEPT_BLOCK >> 20} MiB kept in them when freed (up to '
                f'{KEPT_FREE >> 20} MiB a heap), so large answers reuse warm pages')
    return f'malloc: {arenas}; {kept}'


def _set_by_user(environ: Mapping[str, str], variables: tuple[str, ...],
                 tunables: tuple[str, ...]) -> list[str]:
    """Return the environment variables (of ``variables``, or GLIBC_TUNABLES) that are set."""
    own = [name for name in variables if environ.get(name)]
    if any(t in environ.get('GLIBC_TUNABLES', '') for t in tunables):
        own.append('GLIBC_TUNABLES')
    return own


def user_setting(environ: Mapping[str, str]) -> str | None:
    """Return the environment variable by which the user set the arenas, or None."""
    own = _set_by_user(environ, ('MALLOC_ARENA_MAX',), ('malloc.arena_max',))
    return own[0] if own else None


def user_thresholds(environ: Mapping[str, str]) -> str | None:
    """Return the environment variables by which the user set large blocks, or None."""
    own = _set_by_user(environ, ('MALLOC_MMAP_THRESHOLD_', 'MALLOC_TRIM_THRESHOLD_'),
                       ('malloc.mmap_threshold', 'malloc.trim_threshold'))
    return ', '.join(own) or None


def start_node(module: str, args=None) -> int:
    """Limit the arenas, then import the node's ``module`` and return its ``main(args)``."""
    share_malloc_arenas()
    return importlib.import_module(module).main(args)
