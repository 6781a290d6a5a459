/*
 * A Predict request read into light Python records: see plan_records.h.
 *
 * rosidl's conversion makes a ControlPlan message per plan through its Python setters,
 * each checking its value: 9 ms for a planner's 1,000 plans, every time the interpreter
 * lock held (docs/predictor.md, "A thousand plans"). The predictor reads a plan's
 * header stamp, id, control names and units, step period and values, and never writes
 * them: here each plan is a read-only record of those fields (a struct sequence, as
 * os.stat's result), its names tuples of str and its values a float64 memoryview of one
 * buffer that holds every plan's.
 */

#include "plan_records.h"

#include <string.h>

static PyTypeObject StampType, HeaderType, PlanType, RequestType;

static PyStructSequence_Field STAMP_FIELDS[] = {
  {"sec", "s"}, {"nanosec", "ns"}, {NULL, NULL}};
static PyStructSequence_Field HEADER_FIELDS[] = {
  {"stamp", "the plan's stamp (sec, nanosec)"}, {"frame_id", NULL}, {NULL, NULL}};
static PyStructSequence_Field PLAN_FIELDS[] = {
  {"header", NULL}, {"plan_id", NULL},
  {"control_names", "tuple of str"}, {"control_units", "tuple of str"},
  {"values", "float64 memoryview, row-major (rows, controls)"},
  {"step_period", "s"}, {NULL, NULL}};
static PyStructSequence_Field REQUEST_FIELDS[] = {
  {"plans", "list of Plan"}, {"answer_period", "s"}, {NULL, NULL}};

static PyStructSequence_Desc DESCS[] = {
  {"what_if_c.door.Stamp", "A plan's header stamp, read-only.", STAMP_FIELDS, 2},
  {"what_if_c.door.Header", "A plan's header, read-only.", HEADER_FIELDS, 2},
  {"what_if_c.door.Plan", "A ControlPlan's fields, read-only.", PLAN_FIELDS, 6},
  {"what_if_c.door.Request", "A Predict request's fields, read-only.", REQUEST_FIELDS, 2},
};

int plan_records_init(PyObject * module)
{
  PyTypeObject * types[] = {&StampType, &HeaderType, &PlanType, &RequestType};
  const char * names[] = {"Stamp", "Header", "Plan", "Request"};
  for (int k = 0; k < 4; ++k) {
    if (PyStructSequence_InitType2(types[k], &DESCS[k]) < 0 ||
      PyModule_AddObjectRef(module, names[k], (PyObject *)types[k]) < 0)
    {
      return -1;
    }
  }
  return 0;
}

static PyObject * text(const rosidl_runtime_c__String * s)
{
  /* A client's malformed UTF-8 is replaced, not fatal: the checks then name what is wrong. */
  return PyUnicode_DecodeUTF8(s->data ? s->data : "", (Py_ssize_t)s->size, "replace");
}

static PyObject * texts(const rosidl_runtime_c__String__Sequence * s)
{
  PyObject * out = PyTuple_New((Py_ssize_t)s->size);
  for (size_t i = 0; out && i < s->size; ++i) {
    PyObject * item = text(&s->data[i]);
    if (!item) {Py_CLEAR(out);} else {PyTuple_SET_ITEM(out, (Py_ssize_t)i, item);}
  }
  return out;
}

/* A struct sequence of TYPE from N new references (any NULL: all released, NULL). */
static PyObject * record(PyTypeObject * type, int n, PyObject ** items)
{
  bool complete = true;
  for (int k = 0; k < n; ++k) {complete = complete && items[k];}
  PyObject * out = complete ? PyStructSequence_New(type) : NULL;
  for (int k = 0; k < n; ++k) {
    if (out) {PyStructSequence_SET_ITEM(out, k, items[k]);} else {Py_XDECREF(items[k]);}
  }
  return out;
}

static PyObject * plan_record(const hybrid_predictor_interfaces__msg__ControlPlan * plan,
  PyObject * values)
{
  PyObject * stamp[] = {PyLong_FromLong(plan->header.stamp.sec),
    PyLong_FromUnsignedLong(plan->header.stamp.nanosec)};
  PyObject * header[] = {record(&StampType, 2, stamp), text(&plan->header.frame_id)};
  PyObject * fields[] = {record(&HeaderType, 2, header), text(&plan->plan_id),
    texts(&plan->control_names), texts(&plan->control_units), values,
    PyFloat_FromDouble(plan->step_period)};
  return record(&PlanType, 6, fields);
}

PyObject * request_records(const hybrid_predictor_interfaces__srv__Predict_Request * request)
{
  const hybrid_predictor_interfaces__msg__ControlPlan__Sequence * plans = &request->plans;
  size_t total = 0;
  for (size_t i = 0; i < plans->size; ++i) {total += plans->data[i].values.size;}
  /* Every plan's values in one buffer, each plan's a slice of one float64 view of it. */
  PyObject * buffer = PyBytes_FromStringAndSize(NULL, (Py_ssize_t)(total * sizeof(double)));
  PyObject * bytes_view = buffer ? PyMemoryView_FromObject(buffer) : NULL;
  PyObject * doubles = bytes_view ? PyObject_CallMethod(bytes_view, "cast", "s", "d") : NULL;
  Py_XDECREF(bytes_view);
  PyObject * list = doubles ? PyList_New((Py_ssize_t)plans->size) : NULL;
  size_t at = 0;
  for (size_t i = 0; list && i < plans->size; ++i) {
    const rosidl_runtime_c__double__Sequence * values = &plans->data[i].values;
    if (values->size) {
      memcpy(PyBytes_AS_STRING(buffer) + at * sizeof(double), values->data,
        values->size * sizeof(double));
    }
    PyObject * slice = PySequence_GetSlice(doubles, (Py_ssize_t)at,
      (Py_ssize_t)(at + values->size));
    at += values->size;
    PyObject * plan = slice ? plan_record(&plans->data[i], slice) : NULL;
    if (!plan) {Py_CLEAR(list);} else {PyList_SET_ITEM(list, (Py_ssize_t)i, plan);}
  }
  Py_XDECREF(doubles);
  Py_XDECREF(buffer);
  PyObject * fields[] = {list, list ? PyFloat_FromDouble(request->answer_period) : NULL};
  return record(&RequestType, 2, fields);
}
