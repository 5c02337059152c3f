"""rosbag2 recording and replay without the ROS 2 CLI (ROS-free; the nodes live in actaim2_policy).

Built on ``rosbags`` (record helpers, readers, type system). Files one job each:

  yaml_emit.py    metadata.yaml text in the layout rosbag2's yaml-cpp writes (key order, quoting)
  metadata.py     the version-9 metadata document of a bag (topics, files, QoS as enum names)
  definitions.py  message definitions and type hashes read from installed .msg/.json files,
                  concatenated exactly as rosbag2 stores them
  mcap_file.py    one MCAP storage file: lz4/zstd chunks, summary, and recovery after a write error
  sqlite_file.py  one sqlite3 storage file (rosbag2 schema 4), committed as it goes
  writer.py       a bag directory: storage files, splitting by size or duration, metadata.yaml,
                  what waits in memory written by age (max_chunk_age)
  recorder.py     the writer thread behind a byte-bounded queue, episodes, loss counting
  qos.py          which QoS the recorder subscribes with and the player publishes with
  source.py       reading a bag for replay: per-file, per-topic problems reported, never fatal
  salvage.py      messages before the damage of a truncated MCAP file; finishing such a file
  reindex.py      `actaim2 bag-reindex`: finish the files a recorder that died left open,
                  rebuild metadata.yaml
  playback.py     original timing (rate, start offset, loop), /clock ticks, timing error
"""
