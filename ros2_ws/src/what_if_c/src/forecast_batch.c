/*
 * A batch of Forecast messages written from arrays: see forecast_batch.h.
 *
 * A thousand-plan what-if answer built as Python messages and converted field by field
 * to C took 25 ms of the interpreter's time (docs/predictor.md, "A thousand plans"). Here
 * the batch's shared fields are converted once (its template), each message is a C copy
 * of it, and its rows are copied from the batch's arrays, as
 * ForecastBatch.messages() builds them in Python; the tests compare the two to the byte.
 */

#include "forecast_batch.h"

#include <stddef.h>
#include <string.h>

#include "rosidl_runtime_c/primitives_sequence_functions.h"
#include "rosidl_runtime_c/string_functions.h"

#include "message_class.h"

typedef hybrid_predictor_interfaces__msg__Forecast forecast_t;

/* The float64[] fields a Forecast holds a row of per step (forecast_messages.STEP_ROWS). */
static const struct
{
  const char * name;
  size_t offset;
} STEP_ROWS[] = {
  {"hybrid", offsetof(forecast_t, hybrid)},
  {"physics", offsetof(forecast_t, physics)},
  {"x", offsetof(forecast_t, x)},
  {"y", offsetof(forecast_t, y)},
  {"heading", offsetof(forecast_t, heading)},
  {"z", offsetof(forecast_t, z)},
  {"band_lower", offsetof(forecast_t, band_lower)},
  {"band_upper", offsetof(forecast_t, band_upper)},
  {"bound_available", offsetof(forecast_t, bound_available)},
};
#define N_STEP_ROWS (sizeof(STEP_ROWS) / sizeof(STEP_ROWS[0]))

static rosidl_runtime_c__double__Sequence * row_field(forecast_t * msg, size_t field)
{
  return (rosidl_runtime_c__double__Sequence *)((char *)msg + STEP_ROWS[field].offset);
}

typedef struct
{
  Py_ssize_t count;
  Py_buffer rows[N_STEP_ROWS];
  bool has_row[N_STEP_ROWS];
  Py_buffer stamps, emptied;
  bool has_stamps, has_emptied;
  PyObject * plan_ids, * controls;   /* lists of str, new references */
  forecast_t template;
  bool has_template;
} batch_view_t;

static void release_view(batch_view_t * v)
{
  for (size_t k = 0; k < N_STEP_ROWS; ++k) {
    if (v->has_row[k]) {PyBuffer_Release(&v->rows[k]);}
  }
  if (v->has_stamps) {PyBuffer_Release(&v->stamps);}
  if (v->has_emptied) {PyBuffer_Release(&v->emptied);}
  Py_XDECREF(v->plan_ids);
  Py_XDECREF(v->controls);
  if (v->has_template) {hybrid_predictor_interfaces__msg__Forecast__fini(&v->template);}
}

/* A C-contiguous buffer of FORMAT with NDIM dimensions and COUNT rows; else an error. */
static bool read_array(PyObject * obj, const char * what, const char * format, int ndim,
  Py_ssize_t count, Py_buffer * view)
{
  if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {return false;}
  const char * got = view->format ? view->format : "B";
  if (got[0] == '=' || got[0] == '<' || got[0] == '@') {++got;}
  /* NumPy's int64 is 'l' on LP64 hosts, 'q' elsewhere. */
  bool same = strcmp(got, format) == 0 ||
    (strcmp(format, "q") == 0 && strcmp(got, "l") == 0 && view->itemsize == 8);
  if (!same || view->ndim != ndim || view->shape[0] != count) {
    PyErr_Format(PyExc_ValueError, "a forecast batch's %s must be %d-D '%s' with %zd rows, "
      "got %d-D '%s' with %zd", what, ndim, format, count, view->ndim, got,
      view->ndim ? view->shape[0] : (Py_ssize_t)0);
    PyBuffer_Release(view);
    return false;
  }
  return true;
}

static PyObject * str_list(PyObject * batch, const char * name, Py_ssize_t count)
{
  PyObject * list = PyObject_GetAttrString(batch, name);
  if (list && (!PyList_Check(list) || PyList_GET_SIZE(list) != count)) {
    PyErr_Format(PyExc_ValueError, "a forecast batch's %s must be a list of %zd str", name,
      count);
    Py_CLEAR(list);
  }
  return list;
}

/* The template as a C Forecast: Forecast's own conversion, Forecast's only. */
static bool read_template(PyObject * batch, batch_view_t * v)
{
  PyObject * template = PyObject_GetAttrString(batch, "template");
  if (!template) {return false;}
  PyObject * cls = (PyObject *)Py_TYPE(template);
  PyObject * support = PyObject_GetAttrString((PyObject *)Py_TYPE(cls), "_TYPE_SUPPORT");
  const void * type_support = support && support != Py_None ?
    PyCapsule_GetPointer(support, NULL) : NULL;
  Py_XDECREF(support);
  convert_from_py_t * from_py = capsule_function(cls, "_CONVERT_FROM_PY").from_py;
  PyErr_Clear();
  bool ok = false;
  if (!type_support || !from_py) {
    PyErr_SetString(PyExc_TypeError, "a forecast batch's template must be a Forecast whose "
      "support is loaded (rclpy.type_support.check_for_type_support)");
  } else if (type_support != ROSIDL_GET_MSG_TYPE_SUPPORT(hybrid_predictor_interfaces, msg,
    Forecast))
  {
    PyErr_SetString(PyExc_TypeError,
      "a forecast batch's template must be a hybrid_predictor_interfaces/msg/Forecast");
  } else if (!hybrid_predictor_interfaces__msg__Forecast__init(&v->template)) {
    PyErr_NoMemory();
  } else {
    v->has_template = true;
    ok = from_py(template, &v->template);
    if (!ok && !PyErr_Occurred()) {
      PyErr_SetString(PyExc_ValueError, "a forecast batch's template could not be read");
    }
  }
  Py_DECREF(template);
  return ok;
}

static bool read_rows(PyObject * batch, batch_view_t * v)
{
  PyObject * rows = PyObject_GetAttrString(batch, "rows");
  if (!rows) {return false;}
  if (!PyDict_Check(rows)) {
    Py_DECREF(rows);
    PyErr_SetString(PyExc_TypeError, "a forecast batch's rows must be a dict");
    return false;
  }
  PyObject * name, * values;
  Py_ssize_t position = 0;
  bool ok = true;
  while (ok && PyDict_Next(rows, &position, &name, &values)) {
    const char * text = PyUnicode_Check(name) ? PyUnicode_AsUTF8(name) : NULL;
    size_t k = 0;
    while (text && k < N_STEP_ROWS && strcmp(STEP_ROWS[k].name, text) != 0) {++k;}
    if (!text || k == N_STEP_ROWS) {
      PyErr_Format(PyExc_ValueError, "a forecast batch's rows: %R is no step row of a "
        "Forecast", name);
      ok = false;
    } else {
      ok = read_array(values, text, "d", 2, v->count, &v->rows[k]);
      v->has_row[k] = ok;
    }
  }
  Py_DECREF(rows);
  return ok;
}

static bool read_batch(PyObject * batch, batch_view_t * v)
{
  Py_ssize_t count = PyObject_Length(batch);
  if (count < 0) {return false;}
  v->count = count;
  v->plan_ids = str_list(batch, "plan_ids", count);
  v->controls = v->plan_ids ? str_list(batch, "controls_assumed", count) : NULL;
  if (!v->controls) {return false;}
  PyObject * stamps = PyObject_GetAttrString(batch, "plan_stamps");
  v->has_stamps = stamps && read_array(stamps, "plan_stamps", "q", 2, count, &v->stamps);
  Py_XDECREF(stamps);
  if (!v->has_stamps) {return false;}
  if (v->stamps.shape[1] != 2) {
    PyErr_SetString(PyExc_ValueError, "a forecast batch's plan_stamps must be (B, 2)");
    return false;
  }
  PyObject * emptied = PyObject_GetAttrString(batch, "emptied");
  v->has_emptied = emptied && read_array(emptied, "emptied", "?", 1, count, &v->emptied);
  Py_XDECREF(emptied);
  return v->has_emptied && read_template(batch, v) && read_rows(batch, v);
}

/* Message I's strings: with the interpreter lock (they are read from str objects). */
static bool fill_strings(const batch_view_t * v, Py_ssize_t i, forecast_t * msg)
{
  const char * fields[2];
  PyObject * lists[2] = {v->plan_ids, v->controls};
  for (int k = 0; k < 2; ++k) {
    PyObject * item = PyList_GET_ITEM(lists[k], i);
    fields[k] = PyUnicode_Check(item) ? PyUnicode_AsUTF8(item) : NULL;
    if (!fields[k]) {
      if (!PyErr_Occurred()) {
        PyErr_Format(PyExc_TypeError, "a forecast batch's %s must be str",
          k ? "controls_assumed" : "plan_ids");
      }
      return false;
    }
  }
  if (!rosidl_runtime_c__String__assign(&msg->plan_id, fields[0]) ||
    !rosidl_runtime_c__String__assign(&msg->controls_assumed, fields[1]))
  {
    PyErr_NoMemory();
    return false;
  }
  const int64_t * stamp = (const int64_t *)v->stamps.buf + 2 * i;
  msg->plan_stamp.sec = (int32_t)stamp[0];
  msg->plan_stamp.nanosec = (uint32_t)stamp[1];
  return true;
}

/* Message I but its strings: the template and its rows. Free of Python. */
static bool fill_steps(const batch_view_t * v, Py_ssize_t i, forecast_t * msg)
{
  if (!hybrid_predictor_interfaces__msg__Forecast__copy(&v->template, msg)) {return false;}
  bool emptied = ((const bool *)v->emptied.buf)[i];
  if (emptied) {   /* as forecast_messages.no_steps */
    msg->horizon = 0;
    rosidl_runtime_c__double__Sequence__fini(&msg->band_position_radius);
    return rosidl_runtime_c__double__Sequence__init(&msg->band_position_radius, 0);
  }
  for (size_t k = 0; k < N_STEP_ROWS; ++k) {
    if (!v->has_row[k]) {continue;}
    Py_ssize_t n = v->rows[k].shape[1];
    rosidl_runtime_c__double__Sequence * row = row_field(msg, k);
    rosidl_runtime_c__double__Sequence__fini(row);
    if (!rosidl_runtime_c__double__Sequence__init(row, (size_t)n)) {return false;}
    memcpy(row->data, (const double *)v->rows[k].buf + i * n, (size_t)n * sizeof(double));
  }
  return true;
}

bool fill_forecast_batch(PyObject * batch,
  hybrid_predictor_interfaces__msg__Forecast__Sequence * out)
{
  batch_view_t v;
  memset(&v, 0, sizeof(v));
  bool ok = read_batch(batch, &v);
  if (ok && !hybrid_predictor_interfaces__msg__Forecast__Sequence__init(out, (size_t)v.count)) {
    ok = false;
    PyErr_NoMemory();
  }
  if (ok) {
    bool copied = true;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; copied && i < v.count; ++i) {copied = fill_steps(&v, i, &out->data[i]);}
    Py_END_ALLOW_THREADS
    if (!copied) {PyErr_NoMemory();}
    ok = copied;
  }
  for (Py_ssize_t i = 0; ok && i < v.count; ++i) {ok = fill_strings(&v, i, &out->data[i]);}
  release_view(&v);
  return ok;
}
