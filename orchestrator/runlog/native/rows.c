/* The run log's sample rows written straight to their places in a chunk's records
   (orchestrator/runlog/chunk.py, ChunkBuilder.records). numpy wrote each field of every row
   with a call of its own (about 80 a row) into a block, and then copied the block's rows to
   their places; here one pass writes each row where it goes. Called through ctypes, so the
   GIL is free meanwhile: the log's writer thread fills while the run plans. All of a chunk's
   rows are written in one call (write_records): each time the thread takes the GIL back it
   may have to wait for the run's thread, which then waits for it in turn.

   Byte order: the fields are little-endian; the binding loads this only on little-endian
   hosts. */

#include <stdint.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

/* Row i (width bytes) goes to records + at[i]: the row template (record headers and protobuf
   tags), then for each channel c its sequence number first[c] + i (u32) at sequence_at[c]
   and the sample's time times[i] (u64, ns) at time_at[c] and time_at[c] + 8 (log and publish
   time), then each double field f, values[column[f] * n + i], at double_at[f]. values is
   (columns, n) float64, C order. */
static void fill_rows(uint8_t *records, const int64_t *at, long n, long width,
               const uint8_t *row_template, const uint64_t *times,
               long channels, const int64_t *sequence_at, const uint32_t *first,
               const int64_t *time_at,
               long doubles, const int64_t *double_at, const int64_t *column,
               const double *values)
{
    for (long i = 0; i < n; i++) {
        uint8_t *row = records + at[i];
        memcpy(row, row_template, (size_t)width);
        for (long c = 0; c < channels; c++) {
            uint32_t sequence = first[c] + (uint32_t)i;
            memcpy(row + sequence_at[c], &sequence, 4);
            memcpy(row + time_at[c], &times[i], 8);
            memcpy(row + time_at[c] + 8, &times[i], 8);
        }
        for (long f = 0; f < doubles; f++)
            memcpy(row + double_at[f], &values[column[f] * n + i], 8);
    }
}

/* Rows already encoded (n rows of width bytes, back to back) to records + at[i]. */
static void place_rows(uint8_t *records, const int64_t *at, long n, long width, const uint8_t *rows)
{
    for (long i = 0; i < n; i++)
        memcpy(records + at[i], rows + i * width, (size_t)width);
}

static size_t put_varint(uint8_t *out, uint64_t value)
{
    size_t k = 0;
    while (value >= 0x80) {
        out[k++] = (uint8_t)(value | 0x80);
        value >>= 7;
    }
    out[k++] = (uint8_t)value;
    return k;
}

static size_t varint_size(uint64_t value)
{
    size_t k = 1;
    while (value >= 0x80) {
        value >>= 7;
        k++;
    }
    return k;
}

/* foxglove.FrameTransforms messages, one per row, as orchestrator/runlog/scene.py's
   encode_frame_transforms encodes them: row i at records + at[i] is an MCAP message record
   (channel, sequence[i], times[i] as log and publish time) whose payload is `transforms`
   FrameTransform fields, each: the timestamp times[i] (sec and nsec, both written even when
   0), the frame ids (the constant bytes names[name_at[t]] up to names[name_at[t + 1]]),
   translation x, y, z and rotation x, y, z, w from poses[(i * transforms + t) * 7 ...]. The
   caller places the rows by their sizes (scene.transform_sizes). */
static void fill_transforms(uint8_t *records, const int64_t *at, long n, long channel,
                            const uint32_t *sequence, const uint64_t *times, long transforms,
                            const uint8_t *names, const int64_t *name_at, const double *poses)
{
    for (long i = 0; i < n; i++) {
        uint8_t *row = records + at[i], *p = row + 31, stamp[24];
        uint64_t ns = times[i];
        size_t s = 0;
        stamp[s++] = 0x08;
        s += put_varint(stamp + s, ns / 1000000000u);
        stamp[s++] = 0x10;
        s += put_varint(stamp + s, ns % 1000000000u);
        for (long t = 0; t < transforms; t++) {
            const double *pose = poses + (i * transforms + t) * 7;
            size_t named = (size_t)(name_at[t + 1] - name_at[t]);
            *p++ = 0x0a;  /* FrameTransforms.transforms */
            p += put_varint(p, 1 + varint_size(s) + s + named + 2 + 27 + 2 + 36);
            *p++ = 0x0a;  /* FrameTransform.timestamp */
            p += put_varint(p, s);
            memcpy(p, stamp, s);
            p += s;
            memcpy(p, names + name_at[t], named);
            p += named;
            *p++ = 0x22;  /* translation: Vector3 x, y, z */
            *p++ = 27;
            for (int k = 0; k < 3; k++) {
                *p++ = (uint8_t)((k + 1) << 3 | 1);
                memcpy(p, &pose[k], 8);
                p += 8;
            }
            *p++ = 0x2a;  /* rotation: Quaternion x, y, z, w */
            *p++ = 36;
            for (int k = 0; k < 4; k++) {
                *p++ = (uint8_t)((k + 1) << 3 | 1);
                memcpy(p, &pose[3 + k], 8);
                p += 8;
            }
        }
        uint64_t length = (uint64_t)(p - row) - 9;
        uint16_t id = (uint16_t)channel;
        row[0] = 0x05;  /* MCAP Message */
        memcpy(row + 1, &length, 8);
        memcpy(row + 9, &id, 2);
        memcpy(row + 11, &sequence[i], 4);
        memcpy(row + 15, &ns, 8);
        memcpy(row + 23, &ns, 8);
    }
}

/* Each job: 16 int64, a kind and its arguments (addresses as integers):
   0: place_rows(records, at, n, width, rows)
   1: fill_rows(records, at, n, width, row_template, times, channels, sequence_at, first,
                time_at, doubles, double_at, column, values)
   2: fill_transforms(records, at, n, channel, sequence, times, transforms, names, name_at,
                      poses)
   Returns the index of the first job of an unknown kind, or -1 when all were done. */
#define P(k) ((void *)(intptr_t)job[k])
EXPORT long write_records(const int64_t *jobs, long n_jobs)
{
    for (long j = 0; j < n_jobs; j++) {
        const int64_t *job = jobs + 16 * j;
        switch (job[0]) {
        case 0:
            place_rows(P(1), P(2), (long)job[3], (long)job[4], P(5));
            break;
        case 1:
            fill_rows(P(1), P(2), (long)job[3], (long)job[4], P(5), P(6), (long)job[7], P(8),
                      P(9), P(10), (long)job[11], P(12), P(13), P(14));
            break;
        case 2:
            fill_transforms(P(1), P(2), (long)job[3], (long)job[4], P(5), P(6), (long)job[7],
                            P(8), P(9), P(10));
            break;
        default:
            return j;
        }
    }
    return -1;
}
