"""
Find rosbag2 recordings and read their raw messages, recovering damaged files.

What users hand us: rosbag2 directories (``metadata.yaml`` + ``.mcap`` or ``.db3``), bare
``.mcap`` files, several of either, or folders of them -- and the bags real life makes:
a recorder killed mid-write leaves an ``.mcap`` without its summary section, cut inside
a chunk, and a directory without ``metadata.yaml``.

Intact files are read through rosbags (indexed, fast). A file rosbags cannot open is
scanned record by record with the ``mcap`` library's stream reader, which recovers
every complete record up to the damage; a chunk cut short is decompressed as far as it
goes and its complete messages are kept. Every loss is reported as one line saying
which file, which bytes and which log times. Messages are deserialized with a rosbags
typestore built from the definitions embedded in the bag, then, for bags recorded
without them (rosbag2 before Iron, sqlite3 storage), from folders of ``.msg`` files the
user names (``MessageDefinitions``), from the ROS 2 interface packages installed here,
and last from the ROS 2 Jazzy types.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
import importlib.util
from io import BytesIO
import os
from pathlib import Path
import re
import struct
import zlib

try:  # the standard library's from Python 3.14; rosbags depends on the backport before
    from compression import zstd
except ImportError:
    from backports import zstd
import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel as McapChannel
from mcap.records import Chunk, DataEnd, Footer, Message, Schema
from mcap.stream_reader import StreamReader
from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import Reader, ReaderError
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Nodetype, Typestore
import yaml

from .sources import Recording, RecordingError, format_ns, unique_names

STORAGE_SUFFIXES = ('.mcap', '.db3')
METADATA = 'metadata.yaml'
# rosbag2 names the files of a split recording <name>_<index>.<ext>.
_SPLIT_NAME = re.compile(r'^(?P<stem>.+)_(?P<index>\d+)$')
_MAX_RECORD_BYTES = 1 << 31  # a longer record length is damage, not data
_READ_ERRORS = (ReaderError, McapError, struct.error, ValueError, OSError, EOFError,
                zstd.ZstdError, RuntimeError)


class BagError(RecordingError):
    """A path holds no readable recording."""


class MessageDefinitionError(ValueError):
    """A folder of .msg files cannot be used (missing, no package name, bad file)."""


@dataclass
class Bag(Recording):
    """One recording: the storage files of a rosbag2 directory, or loose .mcap files."""

    whole_directory: bool = False  # read through rosbags as one (file/message compression)


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a bag: its type, message count (None if unknown) and decodability."""

    msgtype: str
    count: int | None
    problem: str | None = None  # why its messages cannot be deserialized


def find_bags(paths: Iterable[str | os.PathLike]) -> list[Bag]:
    """
    Turn command-line paths into recordings.

    A directory with ``metadata.yaml`` is one bag. A bare ``.mcap``/``.db3`` file is one
    bag, except that loose files named ``<stem>_<index>`` beside each other are the
    split files of one recording that lost its ``metadata.yaml``. Other directories are
    searched for both.
    """
    bags: list[Bag] = []
    for raw in paths:
        path = Path(raw)
        if not path.exists():
            raise BagError(f'{path}: no such file or directory')
        if path.is_file():
            if path.suffix not in STORAGE_SUFFIXES:
                raise BagError(f'{path}: not a bag file (expected {"/".join(STORAGE_SUFFIXES)})')
            bags += _group_loose([path])
        elif (path / METADATA).is_file():
            bags.append(_directory_bag(path))
        else:
            found = _search(path)
            if not found:
                raise BagError(f'{path}: no rosbag2 directory or {"/".join(STORAGE_SUFFIXES)} '
                               f'file inside')
            bags += found
    return unique_names(bags)


def _search(root: Path) -> list[Bag]:
    bags: list[Bag] = []
    # Symbolic links to bag directories are followed (a campaign gathered by links), each
    # real directory once (a link back up the tree would loop).
    seen = {root.resolve()}
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        here = Path(dirpath)
        kept = []
        for d in sorted(dirnames):
            real = (here / d).resolve()
            if real not in seen:
                seen.add(real)
                kept.append(d)
        dirnames[:] = kept
        if METADATA in filenames:
            bags.append(_directory_bag(here))
            dirnames.clear()  # its subdirectories belong to it (see _directory_bag)
            continue
        loose = [here / f for f in sorted(filenames) if Path(f).suffix in STORAGE_SUFFIXES]
        if loose:
            group = _group_loose(loose)
            if here != root and len(group) == 1:
                group[0].notes.append(f'{here}: no {METADATA}; reading its '
                                      f'{len(loose)} storage file(s) as one recording')
            bags += group
    return bags


def _group_loose(files: list[Path]) -> list[Bag]:
    groups: dict[tuple[Path, str], list[Path]] = {}
    for f in files:
        match = _SPLIT_NAME.match(f.stem)
        key = (f.parent, match['stem'] if match else f.stem)
        groups.setdefault(key, []).append(f)
    bags = []
    for (parent, stem), members in groups.items():
        members.sort(key=_split_index)
        bag = Bag(name=stem, path=members[0] if len(members) == 1 else parent, files=members)
        if len(members) > 1:
            bag.notes.append(f'{parent}: no {METADATA}; reading {len(members)} files '
                             f'{stem}_*.{members[0].suffix[1:]} as one split recording')
        bags.append(bag)
    return bags


def _split_index(path: Path) -> tuple[int, str]:
    match = _SPLIT_NAME.match(path.stem)
    return (int(match['index']) if match else -1, path.name)


def _directory_bag(path: Path) -> Bag:
    bag = Bag(name=path.name, path=path, files=[])
    try:
        info = yaml.safe_load((path / METADATA).read_text())['rosbag2_bagfile_information']
        listed = [path / Path(p).name for p in info['relative_file_paths']]
        mode = (info.get('compression_mode') or '').lower()
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        bag.notes.append(f'{path / METADATA}: unreadable ({exc}); reading the storage '
                         f'files found beside it')
        listed, mode = [], ''
    if mode in ('file', 'message'):
        bag.whole_directory = True  # rosbags undoes rosbag2's own compression
        bag.files = listed
        return bag
    for f in listed:
        if f.is_file():
            bag.files.append(f)
        else:
            bag.notes.append(f'{path / METADATA} lists {f.name}, which is missing')
    # A recorder that died leaves files the metadata never learnt about (ours keeps
    # the open split in a subdirectory until it is complete).
    known = set(bag.files)
    extra = sorted(f for f in path.rglob('*') if f.suffix in STORAGE_SUFFIXES
                   and f.is_file() and f not in known and f.name not in
                   {g.name for g in listed})
    for f in extra:
        bag.notes.append(f'{f}: not listed in {METADATA} (an interrupted recording?); '
                         f'reading it too')
    bag.files += extra
    bag.files.sort(key=_split_index)
    return bag


@dataclass
class _Conn:
    key: int
    topic: str
    msgtype: str
    msgdef: tuple[str, str] | None  # (format 'msg'|'idl', text)
    count: int | None


class _IndexedFile:
    """A storage file (or rosbag2 directory) that rosbags opens from its index."""

    def __init__(self, path: Path):
        self.path = path
        self.reader = Reader(path)
        self.reader.open()
        self.conns: list[_Conn] = []
        for c in self.reader.connections:
            fmt = {MessageDefinitionFormat.MSG: 'msg',
                   MessageDefinitionFormat.IDL: 'idl'}.get(c.msgdef.format)
            self.conns.append(_Conn(c.id, c.topic, c.msgtype,
                                    (fmt, c.msgdef.data) if fmt else None, c.msgcount))
        self._by_key = {c.id: c for c in self.reader.connections}

    def messages(self, keys: set[int]) -> Iterator[tuple[int, int, bytes]]:
        wanted = [self._by_key[k] for k in keys]
        if wanted:
            for conn, log_ns, raw in self.reader.messages(connections=wanted):
                yield conn.id, log_ns, raw

    def close(self) -> None:
        self.reader.close()


class _ScannedFile:
    """An MCAP file read sequentially by the mcap library, recovering what it can."""

    def __init__(self, path: Path, why: str):
        self.path = path
        self.why = why
        self.losses: list[str] = []
        schemas: dict[int, Schema] = {}
        channels: dict[int, McapChannel] = {}
        counts: Counter[int] = Counter()
        for rec in self._records(report=True):
            if isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, McapChannel):
                channels[rec.id] = rec
            else:
                counts[rec.channel_id] += 1
        self.conns = []
        for cid, ch in sorted(channels.items()):
            schema = schemas.get(ch.schema_id)
            fmt = {'ros2msg': 'msg', 'ros2idl': 'idl', 'omgidl': 'idl'}.get(
                schema.encoding if schema else '')
            msgdef = (fmt, schema.data.decode()) if fmt else None
            if ch.message_encoding != 'cdr':
                self.losses.append(f'{path}: topic {ch.topic} is encoded as '
                                   f'{ch.message_encoding!r}, not CDR; skipped')
                continue
            self.conns.append(_Conn(cid, ch.topic, schema.name if schema else '?', msgdef,
                                    counts[cid]))

    def messages(self, keys: set[int]) -> Iterator[tuple[int, int, bytes]]:
        for rec in self._records(report=False):
            if isinstance(rec, Message) and rec.channel_id in keys:
                yield rec.channel_id, rec.log_time, rec.data

    def close(self) -> None:
        pass

    def _records(self, report: bool) -> Iterator[Schema | McapChannel | Message]:
        """Yield schema, channel and message records; note losses when ``report``."""
        size = self.path.stat().st_size
        with self.path.open('rb') as f:
            pos = 0
            footer = data_end = False
            reader = StreamReader(f, emit_chunks=True, record_size_limit=_MAX_RECORD_BYTES)
            try:
                for rec in reader.records:
                    if isinstance(rec, Chunk):
                        yield from self._chunk(rec, pos, report, cut=False)
                    elif isinstance(rec, (Schema, McapChannel, Message)):
                        yield rec
                    elif isinstance(rec, Footer):
                        footer = True
                    elif isinstance(rec, DataEnd):
                        data_end = True
                    pos = f.tell()
            except _READ_ERRORS as exc:
                if pos == 0:
                    if report:
                        self.losses.append(f'{self.path}: not an MCAP file ({_why(exc)}); '
                                           f'nothing read')
                    return
                if data_end:  # only the index after the data is damaged
                    if report:
                        self.losses.append(f'{self.path}: its summary section is cut short at '
                                           f'byte {size}; no messages lost')
                else:
                    yield from self._cut_record(f, pos, size, report)
            if report and not footer and not data_end:
                self.losses.insert(0, f'{self.path}: {self.why}; it has no summary section '
                                      f'(the recorder did not close it), scanned up to byte '
                                      f'{pos} of {size}')

    def _cut_record(self, f, pos: int, size: int, report: bool):
        """Recover what the record starting at ``pos`` (cut by the end of file) holds."""
        f.seek(pos)
        stream = ReadDataStream(f)
        try:
            opcode = stream.read1()
            stream.read8()
            chunk = Chunk.read(stream) if opcode == Opcode.CHUNK else None
        except _READ_ERRORS:
            opcode, chunk = None, None
        if chunk is None:
            if report:
                kind = {Opcode.MESSAGE: 'a message record'}.get(opcode, 'a record')
                self.losses.append(f'{self.path}: bytes {pos}-{size} (the end of the file) '
                                   f'hold {kind} cut short; lost')
            return
        yield from self._chunk(chunk, pos, report, cut=True)

    def _chunk(self, chunk: Chunk, pos: int, report: bool, cut: bool):
        where = (f'{self.path}: chunk at byte {pos} ({chunk.compression or "uncompressed"}, '
                 f'log times {format_ns(chunk.message_start_time)} to '
                 f'{format_ns(chunk.message_end_time)})')
        try:
            data = _decompress_prefix(chunk)
        except _READ_ERRORS as exc:
            if report:
                self.losses.append(f'{where}: cannot decompress ({_why(exc)}); its messages '
                                   f'are lost')
            return
        complete = len(data) == chunk.uncompressed_size
        if complete and not cut and chunk.uncompressed_crc:
            if zlib.crc32(data) != chunk.uncompressed_crc:
                if report:
                    self.losses.append(f'{where}: checksum mismatch; its messages are lost')
                return
        n = 0
        last = None
        try:
            for rec in StreamReader(BytesIO(data), skip_magic=True, emit_chunks=True).records:
                if isinstance(rec, Message):
                    n += 1
                    last = rec.log_time
                if isinstance(rec, (Schema, McapChannel, Message)):
                    yield rec
        except _READ_ERRORS:
            pass  # the chunk's data ends inside a record: everything before it is kept
        if report and (cut or not complete):
            after = f'after {format_ns(last)}' if last is not None else 'from its start'
            self.losses.append(f'{where} is cut short by the end of the file: recovered '
                               f'{n} message(s); lost those logged {after} up to '
                               f'{format_ns(chunk.message_end_time)}')


def _decompress_prefix(chunk: Chunk) -> bytes:
    """Decompress a chunk's records, as far as they go if the chunk was cut short."""
    if chunk.compression == '':
        return chunk.data
    if chunk.compression == 'zstd':
        return zstd.ZstdDecompressor().decompress(chunk.data)
    if chunk.compression == 'lz4':
        return lz4.frame.LZ4FrameDecompressor().decompress(chunk.data)
    raise ValueError(f'unknown chunk compression {chunk.compression!r}')


def _why(exc: BaseException) -> str:
    text = re.sub(r'\s*\n\s*', ' ', str(exc).strip()).rstrip('.')  # reports are one line
    return text or type(exc).__name__


def _msg_error(exc: BaseException, text: str, msgtype: str) -> str:
    """Say in one line where rosbags' .msg parser stopped in ``text``."""
    # rosbags reports 'Could not parse:', the text it was given, the offset, the rest.
    parts = str(exc).split('\n')
    start = len(f'MSG: {msgtype}\n')  # what get_types_from_msg puts before the text
    if len(parts) > 2 and parts[2].isdigit() and int(parts[2]) >= start:
        line = text.count('\n', 0, int(parts[2]) - start) + 1
        return f'cannot parse line {line}: {text.splitlines()[line - 1].strip()!r}'
    return _why(exc)


class MessageDefinitions:
    """
    Message definitions from folders of ``.msg`` files, for bags recorded without them.

    Each folder is searched recursively, the folders in the order given; the first file
    that defines a type wins. A file laid out as ``<pkg>/msg/Name.msg`` within a folder
    (the folder itself may be ``<pkg>``) defines ``pkg/msg/Name``; any other file takes
    its package from ``package``. Raises MessageDefinitionError (one line) for a missing
    folder, one without ``.msg`` files, a file without a package or one that does not
    parse.
    """

    def __init__(self, dirs: Iterable[str | os.PathLike] = (), package: str | None = None):
        self.dirs = tuple(Path(d) for d in dirs)
        self.package = package
        self.types: dict = {}  # type name -> its field definitions, as rosbags parses them
        self.files: dict[str, Path] = {}  # type name -> the .msg file that defines it
        for root in self.dirs:
            self._load(root)

    def _load(self, root: Path) -> None:
        if not root.is_dir():
            raise MessageDefinitionError(f'--msg-dir {root}: no such directory')
        files = sorted(f for f in root.rglob('*.msg') if f.is_file())
        if not files:
            raise MessageDefinitionError(f'--msg-dir {root}: no .msg files inside')
        top = root.resolve().name  # so that --msg-dir <pkg> finds <pkg>/msg/Name.msg
        for path in files:
            parts = (top, *path.relative_to(root).parts)
            if len(parts) >= 3 and parts[-2] == 'msg':
                pkg = parts[-3]
            elif self.package:
                pkg = self.package
            else:
                raise MessageDefinitionError(
                    f'{path}: no package name for this message (it is not in a <pkg>/msg/ '
                    f'folder); give one with --msg-package NAME')
            msgtype = f'{pkg}/msg/{path.stem}'
            if msgtype in self.types:
                continue
            try:
                text = path.read_text()
            except (OSError, UnicodeDecodeError) as exc:
                raise MessageDefinitionError(f'{path}: cannot read ({_why(exc)})') from None
            try:
                self.types[msgtype] = get_types_from_msg(text, msgtype)[msgtype]
            except Exception as exc:  # noqa: BLE001 - the parser raises several kinds
                raise MessageDefinitionError(f'{path}: not a valid definition of {msgtype} '
                                             f'({_msg_error(exc, text, msgtype)})') from None
            self.files[msgtype] = path

    def to_dict(self) -> dict:
        """Describe the folders and the package given, for a manifest."""
        return {'msg_dirs': [str(d) for d in self.dirs], 'msg_package': self.package}


class BagReader:
    """
    Read one recording's topics and raw messages; losses are collected as text.

    Use as a context manager. ``topics`` and ``typestore`` are available after opening;
    ``messages()`` yields ``(topic, log_time_ns, cdr_bytes)`` per file in file order.
    ``definitions`` supplies the ``.msg`` files of types the bag does not define.
    """

    def __init__(self, bag: Bag, definitions: MessageDefinitions | None = None):
        self.bag = bag
        self.definitions = definitions
        self.losses: list[str] = []
        self.notes: list[str] = list(bag.notes)
        self.topics: dict[str, TopicInfo] = {}
        self.typestore: Typestore = get_typestore(Stores.EMPTY)
        self._files: list[_IndexedFile | _ScannedFile] = []

    def __enter__(self) -> BagReader:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def open(self) -> None:
        """Open every file, collect topics and build the typestore."""
        targets = [self.bag.path] if self.bag.whole_directory else self.bag.files
        for path in targets:
            try:
                self._files.append(_IndexedFile(path))
                continue
            except (ReaderError, OSError, KeyError, ValueError) as exc:
                why = f'rosbags cannot open it ({_why(exc)})'
            if path.suffix != '.mcap':
                self.losses.append(f'{path}: {why}; skipped')
                continue
            scanned = _ScannedFile(path, why)
            self.losses += scanned.losses
            self._files.append(scanned)
        self._build_topics()

    def close(self) -> None:
        """Close every file."""
        for f in self._files:
            f.close()
        self._files.clear()

    def _build_topics(self) -> None:
        types: dict[str, Counter[str]] = {}
        counts: Counter[str] = Counter()
        unknown_count = set()
        defs: dict[str, tuple[str, str]] = {}
        for f in self._files:
            for c in f.conns:
                types.setdefault(c.topic, Counter())[c.msgtype] += c.count or 1
                if c.count is None:
                    unknown_count.add(c.topic)
                counts[c.topic] += c.count or 0
                if c.msgdef and c.msgdef[1].strip():
                    defs.setdefault(c.msgtype, c.msgdef)
        self.typestore, problems = build_typestore(defs, {t for tc in types.values()
                                                          for t in tc}, self.definitions)
        for topic in sorted(types):
            msgtype, _ = types[topic].most_common(1)[0]
            if len(types[topic]) > 1:
                self.notes.append(f'topic {topic} has several types {sorted(types[topic])}; '
                                  f'reading only {msgtype}')
            problem = problems.get(msgtype)
            count = None if topic in unknown_count else counts[topic]
            self.topics[topic] = TopicInfo(msgtype, count, problem)

    def undecodable_lines(self) -> list[str]:
        """One line per topic whose messages cannot be deserialized."""
        return [f'topic {t} has type {i.msgtype}, which {i.problem}; its messages are '
                f'skipped' for t, i in self.topics.items() if i.problem]

    def messages(self, topics: Iterable[str]) -> Iterator[tuple[str, int, bytes]]:
        """
        Raw messages of the given (decodable) topics, file by file, log-time order within one.

        A file that fails while being read is rescanned with the recovery reader from
        the first log time not yet delivered; the failure is added to ``losses``.
        """
        wanted = {t: self.topics[t].msgtype for t in topics
                  if t in self.topics and not self.topics[t].problem}
        for i, f in enumerate(self._files):
            keys = {c.key: c.topic for c in f.conns if wanted.get(c.topic) == c.msgtype}
            last = None
            try:
                for key, log_ns, raw in f.messages(set(keys)):
                    last = log_ns
                    yield keys[key], log_ns, raw
            except _READ_ERRORS as exc:
                if isinstance(f, _ScannedFile) or f.path.is_dir():
                    self.losses.append(f'{f.path}: reading failed ({_why(exc)}); the rest '
                                       f'of the file is lost')
                    continue
                yield from self._rescan(i, f, wanted, last, exc)

    def _rescan(self, i, f, wanted, last, exc):
        self.losses.append(f'{f.path}: reading failed after log time '
                           f'{format_ns(last) if last is not None else "(start)"} '
                           f'({_why(exc)}); rescanning the rest record by record')
        f.close()
        scanned = _ScannedFile(f.path, 'it failed while being read')
        self._files[i] = scanned
        self.losses += scanned.losses
        keys = {c.key: c.topic for c in scanned.conns if wanted.get(c.topic) == c.msgtype}
        for key, log_ns, raw in scanned.messages(set(keys)):
            if last is None or log_ns > last:
                yield keys[key], log_ns, raw


def build_typestore(defs: dict[str, tuple[str, str]], needed: Iterable[str],
                    definitions: MessageDefinitions | None = None,
                    ) -> tuple[Typestore, dict[str, str]]:
    """
    Build a typestore for the ``needed`` types and the types they use.

    Each type's definition comes from the first source that has it: the bag's own
    (``defs``: type -> (format 'msg'|'idl', text)), the ``.msg`` folders of
    ``definitions``, the ROS 2 interface packages installed here, ROS 2 Jazzy's types.
    Returns the store and, for each type in ``needed`` it cannot deserialize, why.
    """
    problems: dict[str, str] = {}
    embedded: dict = {}
    for msgtype, (fmt, text) in defs.items():
        try:
            parsed = (get_types_from_msg(text, msgtype) if fmt == 'msg'
                      else _types_from_idl(text))
        except Exception as exc:  # noqa: BLE001 - any parser failure means "undecodable"
            problems[msgtype] = f'has an embedded definition that does not parse ({_why(exc)})'
            continue
        for name, value in parsed.items():
            embedded.setdefault(name, value)
    local = definitions.types if definitions else {}
    jazzy = get_typestore(Stores.ROS2_JAZZY).fielddefs
    chosen: dict = {}
    todo = [t for t in needed if t not in problems]
    while todo:
        name = todo.pop()
        if name in chosen:
            continue
        for source in (embedded.get, local.get, _installed_definition, jazzy.get):
            if (value := source(name)) is not None:
                chosen[name] = value
                todo += [n for _, desc in value[1] for n in _nested(desc)]
                break
    store = get_typestore(Stores.EMPTY)
    store.register(chosen)
    for msgtype in needed:
        if msgtype in problems:
            continue
        missing = _missing(store.fielddefs, msgtype)
        if missing == msgtype:
            problems[msgtype] = _no_definition(msgtype, definitions)
        elif missing:
            problems[msgtype] = f'uses {missing}, which {_no_definition(missing, definitions)}'
    return store, problems


def _no_definition(msgtype: str, definitions: MessageDefinitions | None) -> str:
    """Why ``msgtype`` is unknown, and what the user can do about it."""
    if not definitions or not definitions.dirs:
        return ('has no definition in the bag or in an installed package and is not a ROS 2 '
                'Jazzy type (give its .msg file with --msg-dir DIR)')
    text = ('has no definition in the bag, the --msg-dir folders or an installed package '
            'and is not a ROS 2 Jazzy type')
    name = msgtype.rsplit('/', 1)[-1]
    near = [t for t in definitions.types if t.rsplit('/', 1)[-1] == name]
    if near:  # most likely the folder layout gave the wrong package name
        text += (f' ({definitions.files[near[0]]} defines {near[0]}; a .msg file takes its '
                 f'package from its folders <pkg>/msg/, else from --msg-package)')
    return text


def _installed_definition(msgtype: str):
    """
    Read the definition of ``pkg/msg/Name`` from an installed interface package, or None.

    The package must be importable as a ROS 2 Python interface package (with a ``msg``
    module); its ``.msg`` file is ``share/<pkg>/msg/Name.msg`` under its ament prefix.
    """
    pkg, kind, name = (msgtype.split('/') + ['', ''])[:3]
    if kind != 'msg' or not pkg.isidentifier() or not name:
        return None
    try:
        spec = importlib.util.find_spec(pkg)
    except (ImportError, ValueError):
        return None
    modules = [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    if not any((m / 'msg').is_dir() for m in modules):
        return None
    shares = []
    try:
        from ament_index_python.packages import get_package_share_directory
        shares.append(Path(get_package_share_directory(pkg)))
    except (ImportError, LookupError, OSError, ValueError):
        pass  # no ament index here, or it lacks the package: look beside the module
    # A prefix holds lib/pythonX.Y/site-packages/<pkg> and share/<pkg> side by side.
    shares += [prefix / 'share' / pkg for m in modules for prefix in m.parents]
    for share in shares:
        path = share / 'msg' / f'{name}.msg'
        if path.is_file():
            try:
                return get_types_from_msg(path.read_text(), msgtype)[msgtype]
            except Exception:  # noqa: BLE001 - an unusable file is as good as none
                return None
    return None


def _types_from_idl(text: str) -> dict:
    sep = '=' * 80 + '\n'
    if not text.startswith(sep + 'IDL: '):
        return get_types_from_idl(text)
    out: dict = {}
    for part in text.split(sep)[1:]:
        out.update(get_types_from_idl(part.split('\n', 1)[1]))
    return out


def _nested(desc) -> Iterator[str]:
    if desc[0] == Nodetype.NAME:
        yield desc[1]
    elif desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        yield from _nested(desc[1][0])


def _missing(fielddefs: dict, msgtype: str, seen: set | None = None) -> str | None:
    """Return the first type that ``msgtype`` is or uses and ``fielddefs`` lacks, or None."""
    seen = set() if seen is None else seen
    if msgtype in seen:
        return None
    seen.add(msgtype)
    if msgtype not in fielddefs:
        return msgtype
    for _, desc in fielddefs[msgtype][1]:
        for name in _nested(desc):
            if missing := _missing(fielddefs, name, seen):
                return missing
    return None
