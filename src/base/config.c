/* config.c: one table of typed keys per struct (cr_config_key): fill the
 * struct from a JSON object (cJSON), refusing unknown keys, wrong types and
 * out-of-range values by name (keys absent from the JSON keep the values the
 * caller put in the struct: its defaults), write it back as JSON, and name
 * the first key two structs differ in. */
#include "crease/base.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static int line_of(const char *text, const char *at) {
    int line = 1;
    for (const char *c = text; c < at && *c; c++)
        line += *c == '\n';
    return line;
}

static const cr_config_key *find_key(const cr_config_key *keys, int nkeys, const char *name) {
    for (int i = 0; i < nkeys; i++)
        if (strcmp(keys[i].name, name) == 0) return &keys[i];
    return NULL;
}

static cr_status set_number(const cr_config_key *k, const cJSON *item, const char *source,
                            void *out, cr_error *err) {
    double v = item->valuedouble;
    if (!isfinite(v))
        return CR_FAIL(err, CR_ERR_CONFIG, "%s: key '%s' must be finite", source, k->name);
    if (k->min <= k->max && (v < k->min || v > k->max))
        return CR_FAIL(err, CR_ERR_CONFIG, "%s: key '%s' = %g is outside [%g, %g]", source, k->name,
                       v, k->min, k->max);
    char *field = (char *)out + k->offset;
    switch (k->type) {
    case CR_CFG_FLOAT:
        *(float *)field = (float)v;
        break;
    case CR_CFG_DOUBLE:
        *(double *)field = v;
        break;
    case CR_CFG_INT:
        if (v != floor(v) || fabs(v) > 2147483647.0)
            return CR_FAIL(err, CR_ERR_CONFIG, "%s: key '%s' must be an integer, got %g", source,
                           k->name, v);
        *(int *)field = (int)v;
        break;
    case CR_CFG_U64:
        if (v != floor(v) || v < 0 || v >= 18446744073709551616.0) /* 2^64 */
            return CR_FAIL(err, CR_ERR_CONFIG,
                           "%s: key '%s' must be a non-negative integer, got %g", source, k->name,
                           v);
        *(uint64_t *)field = (uint64_t)v;
        break;
    default:
        CR_ASSERT(0);
    }
    return CR_OK;
}

static const char *type_name(cr_config_type t) {
    switch (t) {
    case CR_CFG_FLOAT:
    case CR_CFG_DOUBLE:
        return "a number";
    case CR_CFG_INT:
        return "an integer";
    case CR_CFG_U64:
        return "a non-negative integer";
    case CR_CFG_BOOL:
        return "true or false";
    case CR_CFG_STRING:
        return "a string";
    }
    return "?";
}

static cr_status set_key(const cr_config_key *k, const cJSON *item, const char *source, void *out,
                         cr_error *err) {
    char *field = (char *)out + k->offset;
    switch (k->type) {
    case CR_CFG_FLOAT:
    case CR_CFG_DOUBLE:
    case CR_CFG_INT:
    case CR_CFG_U64:
        if (cJSON_IsNumber(item)) return set_number(k, item, source, out, err);
        break;
    case CR_CFG_BOOL:
        if (cJSON_IsBool(item)) {
            *(int *)field = cJSON_IsTrue(item);
            return CR_OK;
        }
        break;
    case CR_CFG_STRING:
        if (cJSON_IsString(item)) {
            if (strlen(item->valuestring) >= k->size)
                return CR_FAIL(err, CR_ERR_CONFIG, "%s: key '%s' is longer than %zu characters",
                               source, k->name, k->size - 1);
            memcpy(field, item->valuestring, strlen(item->valuestring) + 1);
            return CR_OK;
        }
        break;
    }
    return CR_FAIL(err, CR_ERR_CONFIG, "%s: key '%s' must be %s", source, k->name,
                   type_name(k->type));
}

cr_status cr_config_parse_object(const cJSON *obj, const char *source, const cr_config_key *keys,
                                 int nkeys, void *out, cr_error *err) {
    if (!cJSON_IsObject(obj))
        return CR_FAIL(err, CR_ERR_CONFIG, "%s: expected a JSON object", source);
    cr_status st = CR_OK;
    for (const cJSON *item = obj->child; item && st == CR_OK; item = item->next) {
        const cr_config_key *k = find_key(keys, nkeys, item->string);
        if (!k)
            st = CR_FAIL(err, CR_ERR_CONFIG, "%s: unknown key '%s'", source, item->string);
        else
            st = set_key(k, item, source, out, err);
    }
    return st;
}

cr_status cr_config_parse(const char *json_text, const char *source, const cr_config_key *keys,
                          int nkeys, void *out, cr_error *err) {
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(json_text, &end, 1);
    if (!root) {
        const char *at = cJSON_GetErrorPtr();
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%d: malformed JSON", source,
                       at ? line_of(json_text, at) : 1);
    }
    cr_status st =
        cJSON_IsObject(root)
            ? cr_config_parse_object(root, source, keys, nkeys, out, err)
            : CR_FAIL(err, CR_ERR_CONFIG, "%s: expected a JSON object at the top level", source);
    cJSON_Delete(root);
    return st;
}

cJSON *cr_config_to_object(const cr_config_key *keys, int nkeys, const void *in) {
    cJSON *o = cJSON_CreateObject();
    for (int i = 0; o && i < nkeys; i++) {
        const char *f = (const char *)in + keys[i].offset;
        cJSON *v = NULL;
        switch (keys[i].type) {
        case CR_CFG_FLOAT:
            v = cJSON_CreateNumber((double)*(const float *)f);
            break;
        case CR_CFG_DOUBLE:
            v = cJSON_CreateNumber(*(const double *)f);
            break;
        case CR_CFG_INT:
            v = cJSON_CreateNumber(*(const int *)f);
            break;
        case CR_CFG_U64:
            v = cJSON_CreateNumber((double)*(const uint64_t *)f);
            break;
        case CR_CFG_BOOL:
            v = cJSON_CreateBool(*(const int *)f);
            break;
        case CR_CFG_STRING:
            v = cJSON_CreateString(f);
            break;
        }
        if (!v || !cJSON_AddItemToObject(o, keys[i].name, v)) {
            cJSON_Delete(v);
            cJSON_Delete(o);
            return NULL;
        }
    }
    return o;
}

const char *cr_config_diff(const cr_config_key *keys, int nkeys, const void *a, const void *b) {
    for (int i = 0; i < nkeys; i++) {
        const char *x = (const char *)a + keys[i].offset, *y = (const char *)b + keys[i].offset;
        int same = 1;
        switch (keys[i].type) {
        case CR_CFG_FLOAT:
            same = *(const float *)x == *(const float *)y;
            break;
        case CR_CFG_DOUBLE:
            same = *(const double *)x == *(const double *)y;
            break;
        case CR_CFG_INT:
        case CR_CFG_BOOL:
            same = *(const int *)x == *(const int *)y;
            break;
        case CR_CFG_STRING:
            same = strncmp(x, y, keys[i].size) == 0;
            break;
        case CR_CFG_U64:
            same = *(const uint64_t *)x == *(const uint64_t *)y;
            break;
        }
        if (!same) return keys[i].name;
    }
    return NULL;
}

const char *cr_config_absent(const cr_config_key *keys, int nkeys, const cJSON *obj) {
    for (int i = 0; i < nkeys; i++)
        if (!cJSON_GetObjectItemCaseSensitive(obj, keys[i].name)) return keys[i].name;
    return NULL;
}

double cr_config_number(const cr_config_key *k, const void *in) {
    const char *f = (const char *)in + k->offset;
    switch (k->type) {
    case CR_CFG_FLOAT:
        return *(const float *)f;
    case CR_CFG_DOUBLE:
        return *(const double *)f;
    case CR_CFG_INT:
    case CR_CFG_BOOL:
        return *(const int *)f;
    case CR_CFG_U64:
        return (double)*(const uint64_t *)f;
    case CR_CFG_STRING:
        break;
    }
    return 0.0;
}

cr_status cr_config_check(const cr_config_key *keys, int nkeys, const void *in, const char *what,
                          cr_error *err) {
    for (int i = 0; i < nkeys; i++) {
        const cr_config_key *k = &keys[i];
        if (k->type == CR_CFG_STRING || k->type == CR_CFG_BOOL || k->min > k->max) continue;
        double v = cr_config_number(k, in);
        if (!(v >= k->min && v <= k->max))
            return CR_FAIL(err, CR_ERR_INVALID, "%s: %s %g outside [%g, %g]", what, k->name, v,
                           k->min, k->max);
    }
    return CR_OK;
}

cr_status cr_config_load(const char *path, const cr_config_key *keys, int nkeys, void *out,
                         cr_error *err) {
    char *text = NULL;
    CR_TRY(cr_file_read_all(path, &text, NULL, err));
    cr_status st = cr_config_parse(text, path, keys, nkeys, out, err);
    free(text);
    return st;
}
