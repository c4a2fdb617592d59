// Reference peer for Hardcopy's MCAP interop tests: reads an MCAP file with the npm reference
// reader (@mcap/core McapIndexedReader over @mcap/nodejs FileHandleReadable, decompression from
// @mcap/support) and prints one JSON object:
//   {"library", "profile", "messages", "chunks", "channels": {topic: count}, "schemas": {topic:
//    name}, "metadata": [names], "attachments": [names], "statistics": {...}|null,
//    "images": {topic: {"decoded": n, "width", "height", "encoding", "format", "first_bytes": [...] }}}
// Frames on protobuf channels are decoded with protobufjs from the FileDescriptorSet stored in
// the schema, as Foxglove does. Usage: node read_mcap.mjs FILE.mcap
import { open } from "node:fs/promises";
import { McapIndexedReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers, protobufFromBinaryDescriptor } from "@mcap/support";

const file = process.argv[2];
if (!file) {
  console.error("usage: node read_mcap.mjs FILE.mcap");
  process.exit(2);
}
const handle = await open(file, "r");
try {
  const reader = await McapIndexedReader.Initialize({
    readable: new FileHandleReadable(handle),
    decompressHandlers: await loadDecompressHandlers(),
  });
  const channels = {};
  const schemas = {};
  const decoders = new Map();
  for (const [id, ch] of reader.channelsById) {
    channels[ch.topic] = 0;
    const schema = reader.schemasById.get(ch.schemaId);
    schemas[ch.topic] = schema ? schema.name : "";
    if (schema && schema.encoding === "protobuf" && ch.messageEncoding === "protobuf") {
      const root = protobufFromBinaryDescriptor(schema.data);
      decoders.set(id, root.lookupType(schema.name));
    }
  }
  const images = {};
  let messages = 0;
  let lastLogTime = -1n;
  let ordered = true;
  for await (const msg of reader.readMessages()) {
    const ch = reader.channelsById.get(msg.channelId);
    channels[ch.topic] += 1;
    messages += 1;
    if (msg.logTime < lastLogTime) ordered = false;
    lastLogTime = msg.logTime;
    const type = decoders.get(msg.channelId);
    if (type) {
      const m = type.toObject(type.decode(msg.data), { longs: String, bytes: Array });
      const entry = (images[ch.topic] ??= { decoded: 0 });
      entry.decoded += 1;
      entry.width = m.width ?? null;
      entry.height = m.height ?? null;
      entry.encoding = m.encoding ?? null;
      entry.format = m.format ?? null;
      entry.frame_id = m.frameId ?? m.frame_id ?? null;
      entry.timestamp = m.timestamp ? { seconds: String(m.timestamp.seconds), nanos: m.timestamp.nanos ?? 0 } : null;
      entry.data_length = m.data ? m.data.length : 0;
      entry.first_bytes = m.data ? Array.from(m.data.slice(0, 8)) : [];
    }
  }
  const metadata = [];
  for await (const md of reader.readMetadata()) metadata.push(md.name);
  const stats = reader.statistics;
  console.log(
    JSON.stringify({
      library: reader.header.library,
      profile: reader.header.profile,
      messages,
      log_time_ordered: ordered,
      chunks: reader.chunkIndexes.length,
      channels,
      schemas,
      metadata,
      attachments: reader.attachmentIndexes.map((a) => a.name),
      statistics: stats
        ? { message_count: String(stats.messageCount), chunk_count: stats.chunkCount, channel_count: stats.channelCount }
        : null,
      images,
    }),
  );
} finally {
  await handle.close();
}
