/* A small FMI co-simulation master for the cross-platform tests (tests/cross/test_cross.py).
 *
 * It is compiled for each platform the FMUs ship for (gcc for x86_64 Linux, mingw for Windows, zig cc for
 * aarch64 Linux) and run there natively, under Wine or under qemu-aarch64, so that the same calls in the same
 * order reach each platform's binary of the FMUs. It loads one shared library that serves both FMUs (both FMI
 * versions), wires plant and estimator in a loop (paper 000's example), and prints every output of every
 * step as the bits of the double, so that the test can compare the platforms bit for bit. Along the way it
 * saves both FMUs' states half way, serialises them, runs on, restores them from the bytes and replays the
 * second half (which must give the same bits), and makes one bad call of each kind the test expects an FMI
 * status and a log line for.
 *
 *   master LIB VERSION PLANT_TOKEN ESTIMATOR_TOKEN INPUT_FILE NOISE_STD NOISE_SEED
 *          VR_PLANT_U VR_PLANT_Y VR_PLANT_W VR_NOISE_STD VR_NOISE_SEED VR_EST_U VR_EST_Y VR_EST_OUT...
 *
 * INPUT_FILE holds the input sequence as little-endian doubles, NOISE_STD is the bits of a double in hex;
 * VERSION is 2 or 3; the value references come
 * from the FMUs' model descriptions (the test reads them), so nothing here knows the models.
 */
#define __USE_MINGW_ANSI_STDIO 1
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
typedef HMODULE Library;
static Library open_library(const char *path) { return LoadLibraryA(path); }
static void *symbol(Library lib, const char *name) { return (void *)GetProcAddress(lib, name); }
#else
#include <dlfcn.h>
typedef void *Library;
static Library open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(Library lib, const char *name) { return dlsym(lib, name); }
#endif

enum { STATUS_OK = 0, MAX_OUT = 32 };

static int log_lines = 0;

/* ------------------------------------------------------------------------------------------ FMI 2.0 types */
typedef void (*Fmi2Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Fmi2Logger logger;
    void *(*allocate)(size_t, size_t);
    void (*free)(void *);
    void (*step_finished)(void *, int);
    void *environment;
} Fmi2Callbacks;

static void fmi2_logger(void *env, const char *name, int status, const char *category, const char *msg, ...) {
    (void)env;
    va_list args;
    va_start(args, msg);
    fprintf(stderr, "log %s [%s] status %d: ", name, category, status);
    vfprintf(stderr, msg, args);
    fputc('\n', stderr);
    va_end(args);
    log_lines++;
}

/* ------------------------------------------------------------------------------------------ FMI 3.0 types */
typedef void (*Fmi3Log)(void *, int, const char *, const char *);
static void fmi3_logger(void *env, int status, const char *category, const char *msg) {
    (void)env;
    fprintf(stderr, "log [%s] status %d: %s\n", category, status, msg);
    log_lines++;
}

/* The calls the master makes, the same for both versions: each version fills them from the library. */
typedef struct {
    int version;
    Library lib;
    /* FMI 2.0 */
    void *(*instantiate2)(const char *, int, const char *, const char *, const Fmi2Callbacks *, int, int);
    int (*setup2)(void *, int, double, double, int, double);
    int (*set_real2)(void *, const unsigned *, size_t, const double *);
    int (*get_real2)(void *, const unsigned *, size_t, double *);
    int (*set_int2)(void *, const unsigned *, size_t, const int *);
    int (*do_step2)(void *, double, double, int);
    /* FMI 3.0 */
    void *(*instantiate3)(const char *, const char *, const char *, bool, bool, bool, bool, const unsigned *,
                          size_t, void *, Fmi3Log, void *);
    int (*enter_init3)(void *, bool, double, double, bool, double);
    int (*set_real3)(void *, const unsigned *, size_t, const double *, size_t);
    int (*get_real3)(void *, const unsigned *, size_t, double *, size_t);
    int (*set_int3)(void *, const unsigned *, size_t, const int32_t *, size_t);
    int (*do_step3)(void *, double, double, bool, bool *, bool *, bool *, double *);
    /* Both (same C signatures in both versions; only the names differ) */
    int (*enter_init)(void *);
    int (*exit_init)(void *);
    int (*get_state)(void *, void **);
    int (*set_state)(void *, void *);
    int (*free_state)(void *, void **);
    int (*state_size)(void *, void *, size_t *);
    int (*serialize)(void *, void *, unsigned char *, size_t);
    int (*deserialize)(void *, const unsigned char *, size_t, void **);
    void (*free_instance)(void *);
} Api;

static void *need(Library lib, const char *name) {
    void *f = symbol(lib, name);
    if (!f) {
        fprintf(stderr, "the library does not export %s\n", name);
        exit(2);
    }
    return f;
}

#define LOAD(field, name) memcpy(&api->field, &(void *){need(api->lib, name)}, sizeof(void *))

static void load_api(Api *api) {
    if (api->version == 2) {
        LOAD(instantiate2, "fmi2Instantiate");
        LOAD(setup2, "fmi2SetupExperiment");
        LOAD(set_real2, "fmi2SetReal");
        LOAD(get_real2, "fmi2GetReal");
        LOAD(set_int2, "fmi2SetInteger");
        LOAD(do_step2, "fmi2DoStep");
        LOAD(enter_init, "fmi2EnterInitializationMode");
        LOAD(exit_init, "fmi2ExitInitializationMode");
        LOAD(get_state, "fmi2GetFMUstate");
        LOAD(set_state, "fmi2SetFMUstate");
        LOAD(free_state, "fmi2FreeFMUstate");
        LOAD(state_size, "fmi2SerializedFMUstateSize");
        LOAD(serialize, "fmi2SerializeFMUstate");
        LOAD(deserialize, "fmi2DeSerializeFMUstate");
        LOAD(free_instance, "fmi2FreeInstance");
    } else {
        LOAD(instantiate3, "fmi3InstantiateCoSimulation");
        LOAD(enter_init3, "fmi3EnterInitializationMode");
        LOAD(set_real3, "fmi3SetFloat64");
        LOAD(get_real3, "fmi3GetFloat64");
        LOAD(set_int3, "fmi3SetInt32");
        LOAD(do_step3, "fmi3DoStep");
        LOAD(exit_init, "fmi3ExitInitializationMode");
        LOAD(get_state, "fmi3GetFMUState");
        LOAD(set_state, "fmi3SetFMUState");
        LOAD(free_state, "fmi3FreeFMUState");
        LOAD(state_size, "fmi3SerializedFMUStateSize");
        LOAD(serialize, "fmi3SerializeFMUState");
        LOAD(deserialize, "fmi3DeserializeFMUState");
        LOAD(free_instance, "fmi3FreeInstance");
    }
}

static const Fmi2Callbacks callbacks2 = {fmi2_logger, calloc, free, NULL, NULL};

static void *instantiate(const Api *api, const char *name, const char *token) {
    if (api->version == 2)
        return api->instantiate2(name, 1, token, "file:///", &callbacks2, 0, 1);
    return api->instantiate3(name, token, NULL, false, true, false, false, NULL, 0, NULL, fmi3_logger, NULL);
}

static int set_real(const Api *api, void *c, unsigned vr, double v) {
    return api->version == 2 ? api->set_real2(c, &vr, 1, &v) : api->set_real3(c, &vr, 1, &v, 1);
}

static double get_real(const Api *api, void *c, unsigned vr) {
    double v = 0;
    int s = api->version == 2 ? api->get_real2(c, &vr, 1, &v) : api->get_real3(c, &vr, 1, &v, 1);
    if (s != STATUS_OK) {
        fprintf(stderr, "getting value reference %u failed with status %d\n", vr, s);
        exit(1);
    }
    return v;
}

static int set_int(const Api *api, void *c, unsigned vr, int v) {
    int32_t v3 = v;
    return api->version == 2 ? api->set_int2(c, &vr, 1, &v) : api->set_int3(c, &vr, 1, &v3, 1);
}

static int enter_init(const Api *api, void *c) {
    if (api->version == 2) {
        int s = api->setup2(c, 0, 0.0, 0.0, 0, 0.0);
        return s != STATUS_OK ? s : api->enter_init(c);
    }
    return api->enter_init3(c, false, 0.0, 0.0, false, 0.0);
}

static int do_step(const Api *api, void *c, double t, double h) {
    if (api->version == 2)
        return api->do_step2(c, t, h, 0);
    bool event = false, stop = false, early = false;
    double last = 0;
    return api->do_step3(c, t, h, false, &event, &stop, &early, &last);
}

static void check(int status, const char *what) {
    if (status != STATUS_OK) {
        fprintf(stderr, "%s failed with status %d\n", what, status);
        exit(1);
    }
}

/* ---------------------------------------------------------------------------------------------- the run */
typedef struct {
    unsigned plant_u, plant_y, plant_w, noise_std, noise_seed, est_u, est_y;
    unsigned est_out[MAX_OUT];
    int n_out;
} Vrs;

typedef struct {
    void *plant, *est;
} Pair;

/* One step k of the loop (u(k) to the plant, the plant's y(k) and u(k) to the estimator, both step to t_{k+1});
 * the outputs after the step go to `row` (plant y, plant w, then the estimator's outputs). */
static void step(const Api *api, const Pair *p, const Vrs *v, int k, double u, double *row) {
    check(set_real(api, p->plant, v->plant_u, u), "setting the plant's u");
    double y = get_real(api, p->plant, v->plant_y);
    check(set_real(api, p->est, v->est_u, u), "setting the estimator's u");
    check(set_real(api, p->est, v->est_y, y), "setting the estimator's y");
    check(do_step(api, p->plant, k, 1.0), "the plant's step");
    check(do_step(api, p->est, k, 1.0), "the estimator's step");
    row[0] = get_real(api, p->plant, v->plant_y);
    row[1] = get_real(api, p->plant, v->plant_w);
    for (int i = 0; i < v->n_out; i++)
        row[2 + i] = get_real(api, p->est, v->est_out[i]);
}

static uint64_t fnv1a(const unsigned char *bytes, size_t n, uint64_t h) {
    for (size_t i = 0; i < n; i++)
        h = (h ^ bytes[i]) * 0x100000001b3ULL;
    return h;
}

/* Get a state, serialise it, free it: the bytes (malloc'd) and their size. */
static unsigned char *save(const Api *api, void *c, size_t *size) {
    void *state = NULL;
    check(api->get_state(c, &state), "getting the FMU state");
    check(api->state_size(c, state, size), "the serialised state's size");
    unsigned char *bytes = malloc(*size);
    check(api->serialize(c, state, bytes, *size), "serialising the FMU state");
    check(api->free_state(c, &state), "freeing the FMU state");
    return bytes;
}

static void restore(const Api *api, void *c, const unsigned char *bytes, size_t size) {
    void *state = NULL;
    check(api->deserialize(c, bytes, size, &state), "deserialising the FMU state");
    check(api->set_state(c, state), "setting the FMU state");
    check(api->free_state(c, &state), "freeing the FMU state");
}

/* Bad calls, one per instance: each must be answered with fmi2Error/fmi3Error and one log line. */
static void bad_calls(const Api *api, const Pair *p) {
    int before = log_lines;
    int s = set_real(api, p->plant, 0x7fffffffu, 1.0);
    printf("bad value reference: status %d, log lines %d\n", s, log_lines - before);
    before = log_lines;
    s = do_step(api, p->est, 0.0, -1.0);
    printf("negative step: status %d, log lines %d\n", s, log_lines - before);
}

static double *read_input(const char *path, int *n) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        exit(2);
    }
    fseek(f, 0, SEEK_END);
    long bytes = ftell(f);
    fseek(f, 0, SEEK_SET);
    *n = (int)(bytes / 8);
    double *u = malloc((size_t)bytes);
    if (fread(u, 8, (size_t)*n, f) != (size_t)*n) {
        fprintf(stderr, "cannot read %s\n", path);
        exit(2);
    }
    fclose(f);
    return u;
}

static void print_row(int k, const double *row, int width) {
    printf("%d", k);
    for (int i = 0; i < width; i++) {
        uint64_t bits;
        memcpy(&bits, &row[i], 8);
        printf(" %016llx", (unsigned long long)bits);
    }
    printf("\n");
}

int main(int argc, char **argv) {
    if (argc < 16) {
        fprintf(stderr, "usage: see the comment at the top of master.c\n");
        return 2;
    }
    Api api = {0};
    api.version = atoi(argv[2]);
    api.lib = open_library(argv[1]);
    if (!api.lib) {
        fprintf(stderr, "cannot load %s\n", argv[1]);
        return 2;
    }
    load_api(&api);
    int n = 0;
    double *u = read_input(argv[5], &n);
    /* The noise standard deviation as the 16 hex digits of its bits: exact on every C library. */
    uint64_t noise_bits = strtoull(argv[6], NULL, 16);
    double noise_std;
    memcpy(&noise_std, &noise_bits, 8);
    int seed = atoi(argv[7]);
    Vrs v = {0};
    unsigned *fields[] = {&v.plant_u, &v.plant_y, &v.plant_w, &v.noise_std, &v.noise_seed, &v.est_u, &v.est_y};
    for (int i = 0; i < 7; i++)
        *fields[i] = (unsigned)strtoul(argv[8 + i], NULL, 10);
    for (int i = 15; i < argc && v.n_out < MAX_OUT; i++)
        v.est_out[v.n_out++] = (unsigned)strtoul(argv[i], NULL, 10);

    Pair p = {instantiate(&api, "plant", argv[3]), instantiate(&api, "estimator", argv[4])};
    if (!p.plant || !p.est) {
        fprintf(stderr, "instantiation failed\n");
        return 1;
    }
    check(enter_init(&api, p.plant), "the plant's initialisation");
    check(enter_init(&api, p.est), "the estimator's initialisation");
    check(set_real(&api, p.plant, v.noise_std, noise_std), "setting noise_std");
    check(set_int(&api, p.plant, v.noise_seed, seed), "setting noise_seed");
    check(api.exit_init(p.plant), "the plant's end of initialisation");
    check(api.exit_init(p.est), "the estimator's end of initialisation");

    int width = 2 + v.n_out, half = n / 2;
    double *rows = malloc(sizeof(double) * (size_t)width * (size_t)n);
    unsigned char *saved[2] = {NULL, NULL};
    size_t sizes[2] = {0, 0};
    for (int k = 0; k < n; k++) {
        if (k == half) {
            saved[0] = save(&api, p.plant, &sizes[0]);
            saved[1] = save(&api, p.est, &sizes[1]);
        }
        step(&api, &p, &v, k, u[k], rows + (size_t)k * width);
        print_row(k, rows + (size_t)k * width, width);
    }
    /* Back to the middle from the serialised bytes, and the second half again. */
    restore(&api, p.plant, saved[0], sizes[0]);
    restore(&api, p.est, saved[1], sizes[1]);
    int replay_differs = 0;
    double *row = malloc(sizeof(double) * (size_t)width);
    for (int k = half; k < n; k++) {
        step(&api, &p, &v, k, u[k], row);
        replay_differs += memcmp(row, rows + (size_t)k * width, sizeof(double) * (size_t)width) != 0;
    }
    printf("state sizes %zu %zu, hash %016llx, replayed steps differing: %d\n", sizes[0], sizes[1],
           (unsigned long long)fnv1a(saved[1], sizes[1], fnv1a(saved[0], sizes[0], 0xcbf29ce484222325ULL)),
           replay_differs);
    bad_calls(&api, &p);
    /* Both instances are in the error state after the bad calls, from which only freeing leads on. */
    api.free_instance(p.plant);
    api.free_instance(p.est);
    free(row);
    free(rows);
    free(saved[0]);
    free(saved[1]);
    free(u);
    return 0;
}
