"""The shard layout: episodes' rows joined into one Parquet file per shard, written atomically.

`write_shard` numbers the rows, conforms them to the schema, chooses the Parquet encodings
(dictionaries only where values repeat, byte-stream split on floats) and row groups, and stores
the shard's record (its episodes, partial statistics) in the schema metadata.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from echo_data.dataset.schema import (
    ACTION,
    ACTION_EXECUTED,
    PARQUET_COMPRESSION,
    PARQUET_COMPRESSION_LEVEL,
    ROW_GROUP_ROWS,
    SHARD_META_KEY,
    STATE,
    StepLayout,
)
from echo_data.dataset.storage import atomic_path, sha256_file


def conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """Rebuild `table` with exactly `schema` (re-wrapping extension columns that a round trip
    through IPC returned as their plain storage). Chunk by chunk: one chunk per episode keeps
    32-bit list/binary offsets far from overflowing however large a shard is."""
    columns = []
    for f in schema:
        chunks = []
        # a shard written before `action.executed` existed had no executed noise: it is the label
        name = ACTION if f.name == ACTION_EXECUTED and f.name not in table.column_names else f.name
        for chunk in table.column(name).chunks:
            if isinstance(f.type, pa.BaseExtensionType):
                if isinstance(chunk.type, pa.BaseExtensionType):
                    chunk = chunk.storage
                chunk = pa.ExtensionArray.from_storage(f.type, chunk.cast(f.type.storage_type))
            elif chunk.type != f.type:
                chunk = chunk.cast(f.type)
            chunks.append(chunk)
        columns.append(pa.chunked_array(chunks, type=f.type))
    return pa.Table.from_arrays(columns, schema=schema)


@dataclass
class ShardWritten:
    rows: int
    bytes: int
    sha256: str


def write_shard(
    path: Path,
    layout: StepLayout,
    episode_tables: list[pa.Table],
    index_offset: int,
    shard_meta: dict[str, Any],
) -> ShardWritten:
    """Join episodes' rows (in order), number them from `index_offset`, write one Parquet shard
    atomically. `shard_meta` (episode records, partial stats) goes into the schema metadata."""
    schema = layout.schema()
    table = pa.concat_tables(episode_tables) if episode_tables else layout.episode_schema().empty_table()
    n = table.num_rows
    table = table.add_column(2, pa.field("index", pa.int64()), pa.array(np.arange(index_offset, index_offset + n, dtype=np.int64)))
    metadata = dict(schema.metadata)
    metadata[SHARD_META_KEY.encode()] = json.dumps(shard_meta, sort_keys=True, separators=(",", ":")).encode()
    table = conform(table, schema.with_metadata(metadata))
    leaf = ".list.element"  # Parquet leaf paths of the float lists (1 level for vectors, 3 for arrays)
    floats = [ACTION + leaf, ACTION_EXECUTED + leaf, STATE + leaf] + [col + leaf * 3 for col in layout.arrays]
    with atomic_path(path) as tmp, pq.ParquetWriter(
        tmp,
        table.schema,
        compression=PARQUET_COMPRESSION,
        compression_level=PARQUET_COMPRESSION_LEVEL,
        # Dictionaries only where values repeat: on float features they made real shards 1/3
        # larger and slower to read; byte-stream split shaves a little more off the floats.
        use_byte_stream_split=floats,
        use_dictionary=["setting", "skill", "task_index", "skill_index", "episode_index", "audio_path", "audio_sample_rate"],
        write_statistics=True,
        store_schema=True,
    ) as w:
        w.write_table(table, row_group_size=ROW_GROUP_ROWS)
    return ShardWritten(rows=n, bytes=path.stat().st_size, sha256=sha256_file(path))


def read_shard_meta(path: Path) -> dict[str, Any]:
    """The echo-data record a shard carries in its schema metadata."""
    md = pq.read_schema(path).metadata or {}
    raw = md.get(SHARD_META_KEY.encode())
    if raw is None:
        raise ValueError(f"{path.name}: no {SHARD_META_KEY!r} schema metadata")
    return json.loads(raw)
