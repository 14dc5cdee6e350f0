/*
 * analysis._mcap_chunk: the record loop over one decompressed MCAP chunk in C (analysis.mcap_verify's
 * _Reader._scan_python, which stays as the fallback).
 *
 * scan(records, pos, keep, out) walks the records of `records` (a chunk's decompressed bytes) from byte `pos`,
 * appending (channel id, log time ns, message data bytes) to the list `out` for each message whose channel
 * maps to a true value in the dict `keep`, and returns a tuple (code, pos, value, stop) at the first record it
 * does not finish itself:
 *   code 0: the end of the records (pos = their size);
 *   code 1: a schema or channel record at `pos` (value: its opcode, stop: the byte after it). Python files it
 *           (it may declare a channel later messages use, changing `keep`) and calls scan again from `stop`;
 *   code 2..6: the Python loop's error at `pos` (analysis.mcap_verify formats every message in one place):
 *           2 a record header is cut at the end, 3 a record runs past the end, 4 a message is too short,
 *           5 a message's channel is not in `keep` (value: the channel id), 6 a record type that cannot be in a
 *           chunk (value: its opcode).
 * The checks come in the Python loop's order, so a damaged chunk gives the same error at the same record, and
 * the messages appended before it are the same. Sizes in bytes, times in ns; all fields little-endian.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

enum { SCHEMA = 3, CHANNEL = 4, MESSAGE = 5 };
enum { DONE = 0, INNER = 1, CUT = 2, PAST_END = 3, TOO_SHORT = 4, UNDECLARED = 5, NOT_IN_CHUNK = 6 };
enum { RECORD_HEAD = 9, MESSAGE_HEAD = 22 };  /* opcode u8 + length u64; channel u16, seq u32, log/publish u64 */

#define CACHE_SLOTS 16  /* a chunk's messages use a handful of channels: remembered per call, not across calls */

static uint64_t le64(const unsigned char *p) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = (v << 8) | p[i];  /* byte by byte: no alignment or endianness assumption */
    return v;
}

static PyObject *result(int code, Py_ssize_t pos, unsigned long long value, Py_ssize_t stop) {
    return Py_BuildValue("(inKn)", code, pos, value, stop);
}

static PyObject *scan(PyObject *self, PyObject *args) {
    PyObject *records, *keep, *out;
    Py_ssize_t pos;
    if (!PyArg_ParseTuple(args, "O!nO!O!:scan", &PyBytes_Type, &records, &pos, &PyDict_Type, &keep,
                          &PyList_Type, &out))
        return NULL;
    const unsigned char *buf = (const unsigned char *)PyBytes_AS_STRING(records);
    const Py_ssize_t size = PyBytes_GET_SIZE(records);
    if (pos < 0 || pos > size) {
        PyErr_SetString(PyExc_ValueError, "scan: start position outside the records");
        return NULL;
    }
    /* channel + 1 (0: empty slot) -> the truth of keep[channel]. Only the reader's _inner changes keep (on a
       channel record), and it runs between calls: so the cache lives for one call and stays right */
    int32_t cached[CACHE_SLOTS] = {0};
    int wanted[CACHE_SLOTS] = {0};
    while (pos < size) {
        /* pos + RECORD_HEAD <= size, written so that nothing can overflow */
        if (size - pos < RECORD_HEAD) return result(CUT, pos, 0, 0);
        const unsigned char *rec = buf + pos;
        const int opcode = rec[0];
        const uint64_t length = le64(rec + 1);
        /* the length is the file's: up to 2**64 - 1, so compare it with what is left instead of adding it */
        if (length > (uint64_t)(size - pos - RECORD_HEAD)) return result(PAST_END, pos, 0, 0);
        const Py_ssize_t stop = pos + RECORD_HEAD + (Py_ssize_t)length;
        if (opcode == MESSAGE) {
            if (length < MESSAGE_HEAD) return result(TOO_SHORT, pos, 0, 0);
            /* the message header lies inside the record, and the record inside the chunk (checked above) */
            const unsigned channel = (unsigned)rec[RECORD_HEAD] | ((unsigned)rec[RECORD_HEAD + 1] << 8);
            const int slot = (int)(channel % CACHE_SLOTS);
            int want;
            if (cached[slot] == (int32_t)channel + 1) {
                want = wanted[slot];
            } else {
                PyObject *key = PyLong_FromUnsignedLong(channel);
                if (key == NULL) return NULL;
                PyObject *value = PyDict_GetItemWithError(keep, key);  /* borrowed */
                Py_DECREF(key);
                if (value == NULL) {
                    if (PyErr_Occurred()) return NULL;
                    return result(UNDECLARED, pos, channel, 0);
                }
                want = PyObject_IsTrue(value);
                if (want < 0) return NULL;
                cached[slot] = (int32_t)channel + 1;
                wanted[slot] = want;
            }
            if (want) {
                /* log time: after the channel (u16) and the sequence number (u32) */
                const uint64_t log_time = le64(rec + RECORD_HEAD + 6);
                PyObject *item = PyTuple_New(3);
                if (item == NULL) return NULL;
                PyObject *c = PyLong_FromUnsignedLong(channel);
                PyObject *t = PyLong_FromUnsignedLongLong(log_time);
                PyObject *d = PyBytes_FromStringAndSize((const char *)rec + RECORD_HEAD + MESSAGE_HEAD,
                                                        (Py_ssize_t)length - MESSAGE_HEAD);
                if (c == NULL || t == NULL || d == NULL) {
                    Py_XDECREF(c);
                    Py_XDECREF(t);
                    Py_XDECREF(d);
                    Py_DECREF(item);
                    return NULL;
                }
                PyTuple_SET_ITEM(item, 0, c);
                PyTuple_SET_ITEM(item, 1, t);
                PyTuple_SET_ITEM(item, 2, d);
                int failed = PyList_Append(out, item);
                Py_DECREF(item);
                if (failed) return NULL;
            }
        } else if (opcode == SCHEMA || opcode == CHANNEL) {
            return result(INNER, pos, (unsigned long long)opcode, stop);
        } else {
            return result(NOT_IN_CHUNK, pos, (unsigned long long)opcode, 0);
        }
        pos = stop;
    }
    return result(DONE, pos, 0, 0);
}

static PyMethodDef methods[] = {
    {"scan", scan, METH_VARARGS,
     "scan(records, pos, keep, out) -> (code, pos, value, stop): one MCAP chunk's records from byte pos; "
     "wanted messages' (channel, log time ns, data) appended to out"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "analysis._mcap_chunk",
    "The record loop over one decompressed MCAP chunk in C (the same messages and errors as "
    "analysis.mcap_verify's Python loop).", -1,
    methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__mcap_chunk(void) { return PyModule_Create(&module); }
