/* bcryptprimitives.dll for Wine 8.0, which lacks it (every Windows from 10 on has it). Rust's standard library
 * imports ProcessPrng from it for random numbers (HashMap keys); this forwards to RtlGenRandom (exported by
 * advapi32 as SystemFunction036), which Wine has. Only for running the tests under Wine: it is put beside the
 * test master, never into an FMU. */
#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length > 0) {
        ULONG chunk = length > 0x7fffffff ? 0x7fffffff : (ULONG)length;
        if (!SystemFunction036(data, chunk))
            return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
