"""vessel_ros_bridge.allocator: a node's threads share two malloc arenas (glibc)."""

import ctypes
import json
import os
import subprocess
import sys

import pytest

from vessel_ros_bridge import allocator

# The arenas glibc has made so far: malloc_info(3) writes one <heap nr=...> per arena.
COUNT_ARENAS = """
import ctypes, os, tempfile
def arenas():
    libc = ctypes.CDLL(None)
    libc.fopen.restype = ctypes.c_void_p
    libc.malloc_info.argtypes = [ctypes.c_int, ctypes.c_void_p]
    libc.fclose.argtypes = [ctypes.c_void_p]
    path = os.path.join(tempfile.mkdtemp(), 'malloc_info.xml')
    stream = libc.fopen(path.encode(), b'w')
    libc.malloc_info(0, stream)
    libc.fclose(stream)
    return open(path).read().count('<heap nr=')
"""

# In a process of its own (mallopt holds for the whole process): six threads allocate
# while all are alive (an exited thread's arena goes to the next one), each from the
# arena glibc gives it; then the arenas are counted.
PROBE = COUNT_ARENAS + """
import json, sys, threading
from vessel_ros_bridge.allocator import share_malloc_arenas
note = share_malloc_arenas() if sys.argv[1] == 'shared' else ''
libc = ctypes.CDLL(None)
libc.malloc.restype = ctypes.c_void_p
kept, alive = [], threading.Barrier(7)
def allocate():
    kept.append(libc.malloc(1 << 16))
    alive.wait()
threads = [threading.Thread(target=allocate) for _ in range(6)]
for t in threads:
    t.start()
alive.wait()
print(json.dumps({'note': note, 'arenas': arenas()}))
"""

glibc = pytest.mark.skipif(not hasattr(ctypes.CDLL(None), 'gnu_get_libc_version'),
                           reason="malloc arenas are glibc's")


USER_MALLOC = ('MALLOC_ARENA_MAX', 'MALLOC_MMAP_THRESHOLD_', 'MALLOC_TRIM_THRESHOLD_',
               'GLIBC_TUNABLES')


def probe(mode: str, code: str = PROBE, **env) -> dict:
    environ = {k: v for k, v in os.environ.items() if k not in USER_MALLOC}
    out = subprocess.run([sys.executable, '-c', code, mode], env={**environ, **env},
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


@glibc
def test_threads_share_two_arenas():
    control = probe('glibc')
    shared = probe('shared')
    # Without the limit each of the six threads was given an arena of its own.
    assert control['arenas'] >= 4
    assert shared['arenas'] == allocator.ARENAS == 2
    assert shared['note'].startswith(
        'malloc: 2 arenas shared by all threads, so freed memory is reused; blocks up to 32 '
        'MiB kept in them when freed')


@glibc
def test_a_users_own_arena_setting_is_left_as_set():
    user = probe('shared', MALLOC_ARENA_MAX='3')
    assert user['note'].startswith(
        'malloc: arenas set by the user (MALLOC_ARENA_MAX), left as set; blocks up to')
    assert user['arenas'] == 3      # the user's limit holds, not ours


# A 20 MB block, as a thousand-plan answer's: mapped on its own and given back when freed
# (glibc's default), or taken from the arena and kept there, its pages warm for the next.
LARGE_BLOCK = """
import ctypes, json, sys
from vessel_ros_bridge.allocator import share_malloc_arenas
note = share_malloc_arenas() if sys.argv[1] == 'shared' else ''
class Info(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        'arena', 'ordblks', 'smblks', 'hblks', 'hblkhd', 'usmblks', 'fsmblks', 'uordblks',
        'fordblks', 'keepcost')]
libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Info
libc.malloc.restype = ctypes.c_void_p
libc.free.argtypes = [ctypes.c_void_p]
before = libc.mallinfo2().hblks
block = libc.malloc(20 << 20)
mapped = libc.mallinfo2().hblks - before
libc.free(block)
print(json.dumps({'note': note, 'mapped': mapped, 'kept': libc.mallinfo2().fordblks}))
"""


@glibc
def test_large_blocks_stay_in_the_arenas_when_freed():
    control, shared = probe('glibc', LARGE_BLOCK), probe('shared', LARGE_BLOCK)
    assert control['mapped'] == 1 and control['kept'] < 20 << 20
    assert shared['mapped'] == 0 and shared['kept'] >= 20 << 20
    user = probe('shared', LARGE_BLOCK, MALLOC_TRIM_THRESHOLD_='131072')
    assert user['note'].endswith('large blocks as the user set them (MALLOC_TRIM_THRESHOLD_)')
    assert user['mapped'] == 1     # glibc's own mapping: the user's setting alone holds


@pytest.mark.parametrize(('environ', 'expected'), [
    ({'MALLOC_MMAP_THRESHOLD_': '65536'}, 'MALLOC_MMAP_THRESHOLD_'),
    ({'GLIBC_TUNABLES': 'glibc.malloc.trim_threshold=1'}, 'GLIBC_TUNABLES'),
    ({'MALLOC_ARENA_MAX': '4'}, None),
])
def test_user_thresholds_names_the_variables_that_set_large_blocks(environ, expected):
    assert allocator.user_thresholds(environ) == expected


@pytest.mark.parametrize(('environ', 'expected'), [
    ({'MALLOC_ARENA_MAX': '4'}, 'MALLOC_ARENA_MAX'),
    ({'GLIBC_TUNABLES': 'glibc.malloc.arena_max=4'}, 'GLIBC_TUNABLES'),
    ({'GLIBC_TUNABLES': 'glibc.malloc.mmap_threshold=65536'}, None),
    ({'MALLOC_ARENA_MAX': ''}, None),
    ({}, None),
])
def test_user_setting_names_the_variable_that_sets_the_arenas(environ, expected):
    assert allocator.user_setting(environ) == expected


# A node's console entry must limit the arenas before anything starts threads: its
# module imports none of numpy, rclpy or jax, and the node module imported after the
# limit allocates from two arenas (four threads start; three arenas without the limit).
ENTRY = """
import importlib, json, sys
entry = importlib.import_module(sys.argv[1] + '.start')
heavy = sorted(m for m in ('numpy', 'rclpy', 'jax') if m in sys.modules)
if sys.argv[2] == 'limited':
    from vessel_ros_bridge.allocator import share_malloc_arenas
    share_malloc_arenas()
importlib.import_module(sys.argv[1] + '.node')
""" + COUNT_ARENAS + """
print(json.dumps({'heavy': heavy, 'arenas': arenas()}))
"""


@glibc
def test_the_predictors_entry_limits_the_arenas_before_its_imports_start_threads():
    def run(mode):
        out = subprocess.run([sys.executable, '-c', ENTRY, 'hybrid_predictor', mode],
                             capture_output=True, text=True, check=True)
        return json.loads(out.stdout.strip().splitlines()[-1])
    limited, control = run('limited'), run('glibc')
    assert limited['heavy'] == [] and control['heavy'] == []
    assert control['arenas'] >= 3
    assert limited['arenas'] <= allocator.ARENAS


@pytest.mark.parametrize('package', ['hybrid_predictor', 'ship_sim_node'])
def test_a_nodes_entry_imports_nothing_that_starts_threads(package):
    code = (f'import sys, {package}.start; '
            "print(sorted(m for m in ('numpy', 'rclpy', 'jax') if m in sys.modules))")
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == '[]'
