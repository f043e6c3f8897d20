/* The run log's sample rows written straight to their places in a chunk's records
   (orchestrator/runlog/chunk.py, ChunkBuilder.records). numpy wrote each field of every row
   with a call of its own (about 80 a row) into a block, and then copied the block's rows to
   their places; here one pass writes each row where it goes. Called through ctypes, so the
   GIL is free meanwhile: the log's writer thread fills while the run plans.

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
EXPORT void fill_rows(uint8_t *records, const int64_t *at, long n, long width,
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
EXPORT void place_rows(uint8_t *records, const int64_t *at, long n, long width, const uint8_t *rows)
{
    for (long i = 0; i < n; i++)
        memcpy(records + at[i], rows + i * width, (size_t)width);
}
