/*
 * _door: the predictor's what-if service, its admission and its "busy" answers in C.
 *
 * A thread of its own waits on the service alone, takes every request and admits at
 * most CAPACITY at a time: an admitted request is queued for the node's Python
 * (Door.take), whose answer goes back through Door.answer; any other is answered
 * "busy" at once, on this thread, without the interpreter. In rclpy the same refusal
 * needed the interpreter lock several times (the executor's wake, the take, the
 * callback, the send), each time behind the forecasts' Python work: 37-51 ms at p99
 * under the soak (docs/predictor.md, "Soak benchmark").
 *
 * A busy answer says when to come back (retry_after, s of wall time): the running
 * request's expected end for the first client refused, one service time later for the
 * next, and so on up to LONGEST, as if they stood in a queue the node does not hold.
 * The service time is the running mean (weight SMOOTHING for the newest) of the time
 * from an admitted request's start (its admission, or the previous answer if later) to
 * its answer. Times are CLOCK_MONOTONIC seconds. Hint implements this, and Door uses
 * the same functions; Hint exists for the tests.
 */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "rcl/rcl.h"
#include "rcutils/allocator.h"
#include "rcutils/error_handling.h"
#include "rmw/rmw.h"
#include "rmw/serialized_message.h"
#include "rosidl_runtime_c/string_functions.h"

#include "hybrid_predictor_interfaces/srv/predict.h"

#include "forecast_batch.h"
#include "message_class.h"
#include "plan_records.h"
#include "rcl_check.h"

#define MAX_CAPACITY 64

static double monotonic_s(void)
{
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* ------------------------------------------------------------------ the retry hint */

typedef struct
{
  double longest, smoothing;
  double service_time;          /* s; NAN until an answer has been given */
  double admitted[MAX_CAPACITY];  /* admission times of the requests in progress, in order */
  int count;
  double last_finish, booked;   /* -INFINITY until set */
} hint_t;

static void hint_init(hint_t * h, double longest, double smoothing)
{
  memset(h, 0, sizeof(*h));
  h->longest = longest;
  h->smoothing = smoothing;
  h->service_time = NAN;
  h->last_finish = h->booked = -INFINITY;
}

static bool hint_admitted(hint_t * h, double now)
{
  if (h->count == MAX_CAPACITY) {return false;}
  h->admitted[h->count++] = now;
  return true;
}

static bool hint_finished(hint_t * h, double admitted_at, double now)
{
  int k = 0;
  while (k < h->count && h->admitted[k] != admitted_at) {++k;}
  if (k == h->count) {return false;}
  memmove(&h->admitted[k], &h->admitted[k + 1], (size_t)(h->count - k - 1) * sizeof(double));
  h->count--;
  /* Its service began when it was admitted or when the one before it was answered. */
  double took = now - fmax(admitted_at, h->last_finish);
  h->last_finish = now;
  h->service_time = isnan(h->service_time) ? took :
    h->service_time + h->smoothing * (took - h->service_time);
  return true;
}

static double hint_refused(hint_t * h, double now)
{
  if (h->count == 0) {return 0.0;}
  double step, next_free;
  if (isnan(h->service_time)) {
    /* No answer yet to learn from: the running request is taken as half done. */
    step = now - h->admitted[0];
    next_free = now + step;
  } else {
    step = h->service_time;
    next_free = fmax(h->admitted[0], h->last_finish) + step;
  }
  h->booked = fmin(fmax(fmax(h->booked + step, next_free), now), now + h->longest);
  return h->booked - now;
}

static int hint_arguments(double longest, double smoothing)
{
  if (!(longest > 0)) {
    PyErr_Format(PyExc_ValueError, "longest must be > 0 s, got %g", longest);
    return -1;
  }
  if (!(smoothing > 0 && smoothing <= 1)) {
    PyErr_Format(PyExc_ValueError, "smoothing must be in (0, 1], got %g", smoothing);
    return -1;
  }
  return 0;
}

typedef struct
{
  PyObject_HEAD
  hint_t hint;
} HintObject;

static int Hint_init(HintObject * self, PyObject * args, PyObject * kwargs)
{
  static char * names[] = {"longest", "smoothing", NULL};
  double longest = 0, smoothing = 0.2;
  if (!PyArg_ParseTupleAndKeywords(args, kwargs, "d|d", names, &longest, &smoothing)) {
    return -1;
  }
  if (hint_arguments(longest, smoothing) < 0) {return -1;}
  hint_init(&self->hint, longest, smoothing);
  return 0;
}

static PyObject * Hint_admitted(HintObject * self, PyObject * args)
{
  double now;
  if (!PyArg_ParseTuple(args, "d", &now)) {return NULL;}
  if (!hint_admitted(&self->hint, now)) {
    return PyErr_Format(PyExc_ValueError, "more than %d requests in progress", MAX_CAPACITY);
  }
  Py_RETURN_NONE;
}

static PyObject * Hint_finished(HintObject * self, PyObject * args)
{
  double admitted_at, now;
  if (!PyArg_ParseTuple(args, "dd", &admitted_at, &now)) {return NULL;}
  if (!hint_finished(&self->hint, admitted_at, now)) {
    return PyErr_Format(PyExc_ValueError, "no request admitted at %g", admitted_at);
  }
  Py_RETURN_NONE;
}

static PyObject * Hint_refused(HintObject * self, PyObject * args)
{
  double now;
  if (!PyArg_ParseTuple(args, "d", &now)) {return NULL;}
  return PyFloat_FromDouble(hint_refused(&self->hint, now));
}

static PyObject * Hint_service_time(HintObject * self, void * closure)
{
  (void)closure;
  if (isnan(self->hint.service_time)) {Py_RETURN_NONE;}
  return PyFloat_FromDouble(self->hint.service_time);
}

static PyMethodDef HINT_METHODS[] = {
  {"admitted", (PyCFunction)Hint_admitted, METH_VARARGS,
    "admitted(now): note a request admitted at now (s)."},
  {"finished", (PyCFunction)Hint_finished, METH_VARARGS,
    "finished(admitted_at, now): note the answer, at now, of the request admitted at "
    "admitted_at."},
  {"refused", (PyCFunction)Hint_refused, METH_VARARGS,
    "refused(now) -> s from now after which a refused client should retry."},
  {NULL, NULL, 0, NULL}
};

static PyGetSetDef HINT_GETSET[] = {
  {"service_time", (getter)Hint_service_time, NULL,
    "The running mean service time (s), None until a request was answered.", NULL},
  {NULL, NULL, NULL, NULL, NULL}
};

static PyTypeObject HintType = {
  PyVarObject_HEAD_INIT(NULL, 0)
  .tp_name = "what_if_c._door.Hint",
  .tp_basicsize = sizeof(HintObject),
  .tp_flags = Py_TPFLAGS_DEFAULT,
  .tp_doc = "Hint(longest, smoothing=0.2): the retry time of busy answers (module doc).",
  .tp_new = PyType_GenericNew,
  .tp_init = (initproc)Hint_init,
  .tp_methods = HINT_METHODS,
  .tp_getset = HINT_GETSET,
};

/* ------------------------------------------------------------------ the door */

typedef struct
{
  bool used;
  bool answering;        /* its answer is being sent: the token is spent */
  unsigned generation;   /* told apart from an earlier request in the same slot */
  rmw_request_id_t id;
  double admitted_at;
  hybrid_predictor_interfaces__srv__Predict_Request * request;   /* until take() */
} slot_t;

typedef struct
{
  PyObject_HEAD
  rcl_node_t * node;
  rcl_service_t service;
  rcl_guard_condition_t wake;
  rcl_wait_set_t wait_set;
  bool ready;            /* the rcl objects above exist */
  pthread_t thread;
  bool running;
  pthread_mutex_t lock;
  pthread_cond_t waiting;   /* a request was queued for take(), or the door closes */
  pthread_cond_t idle;   /* no Python thread is sending on the service */
  int sending;           /* Python threads sending on the service now */
  int capacity;
  slot_t slots[MAX_CAPACITY];
  hint_t hint;
  long requests, refused;
  /* Admitted requests not yet taken, in order: slot indices, as a ring (each admitted
     request holds a slot, so at most capacity wait). */
  int queue[MAX_CAPACITY];
  int queue_first, queued;
  bool closing;          /* the thread stops; take() gives None once the queue is empty */
  bool shut;             /* close() under way: nothing more is sent */
  char failure[1200];    /* why the door's thread stopped, if it did */
  PyObject * response_class;
  convert_from_py_t * response_from_py;
  hybrid_predictor_interfaces__srv__Predict_Response refusal;   /* the thread's own */
} DoorObject;

static void note_failure(DoorObject * d, const char * what, rcl_ret_t ret)
{
  pthread_mutex_lock(&d->lock);
  if (!d->failure[0]) {
    snprintf(d->failure, sizeof(d->failure), "%s failed (%d): %s", what, (int)ret,
      rcutils_get_error_string().str);
  }
  rcutils_reset_error();
  pthread_mutex_unlock(&d->lock);
}

/* Answer a request with success = false and MESSAGE; on the door's thread only. */
static void answer_refusal(DoorObject * d, rmw_request_id_t * id, const char * message,
  double retry_after)
{
  d->refusal.success = false;
  d->refusal.retry_after = retry_after;
  if (!rosidl_runtime_c__String__assign(&d->refusal.message, message)) {
    note_failure(d, "rosidl_runtime_c__String__assign", RCL_RET_BAD_ALLOC);
    return;
  }
  rcl_ret_t ret = rcl_send_response(&d->service, id, &d->refusal);
  if (ret != RCL_RET_OK) {note_failure(d, "rcl_send_response", ret);}
}

/* Take every request waiting; admit or refuse each. Return false if the take failed. */
static bool take_requests(DoorObject * d)
{
  for (;;) {
    hybrid_predictor_interfaces__srv__Predict_Request * request =
      hybrid_predictor_interfaces__srv__Predict_Request__create();
    if (!request) {
      note_failure(d, "creating a request message", RCL_RET_BAD_ALLOC);
      return false;
    }
    rmw_service_info_t info;
    rcl_ret_t ret = rcl_take_request_with_info(&d->service, &info, request);
    if (ret != RCL_RET_OK) {
      hybrid_predictor_interfaces__srv__Predict_Request__destroy(request);
      if (ret == RCL_RET_SERVICE_TAKE_FAILED) {return true;}
      note_failure(d, "rcl_take_request_with_info", ret);
      return false;
    }
    double now = monotonic_s();
    pthread_mutex_lock(&d->lock);
    d->requests++;
    int slot = -1;
    for (int k = 0; k < d->capacity && slot < 0; ++k) {
      if (!d->slots[k].used) {slot = k;}
    }
    if (slot >= 0) {
      slot_t * s = &d->slots[slot];
      s->used = true;
      s->generation = (s->generation + 1) & 0xffffff;   /* tokens are 32 bits */
      s->id = info.request_id;
      s->admitted_at = now;
      s->request = request;
      hint_admitted(&d->hint, now);
      d->queue[(d->queue_first + d->queued++) % MAX_CAPACITY] = slot;
      pthread_cond_signal(&d->waiting);
      pthread_mutex_unlock(&d->lock);
      continue;
    }
    d->refused++;
    double retry_after = hint_refused(&d->hint, now);
    pthread_mutex_unlock(&d->lock);
    hybrid_predictor_interfaces__srv__Predict_Request__destroy(request);
    char message[160];
    snprintf(message, sizeof(message), "busy: %d requests in progress; retry in %.2f s",
      d->capacity, retry_after);
    answer_refusal(d, &info.request_id, message, retry_after);
  }
}

static void * door_main(void * arg)
{
  DoorObject * d = arg;
  for (;;) {
    pthread_mutex_lock(&d->lock);
    bool closing = d->closing;
    pthread_mutex_unlock(&d->lock);
    if (closing) {break;}
    rcl_ret_t ret = rcl_wait_set_clear(&d->wait_set);
    if (ret == RCL_RET_OK) {ret = rcl_wait_set_add_service(&d->wait_set, &d->service, NULL);}
    if (ret == RCL_RET_OK) {
      ret = rcl_wait_set_add_guard_condition(&d->wait_set, &d->wake, NULL);
    }
    if (ret == RCL_RET_OK) {ret = rcl_wait(&d->wait_set, -1);}
    if (ret == RCL_RET_TIMEOUT) {continue;}
    if (ret != RCL_RET_OK) {
      note_failure(d, "waiting for requests", ret);
      break;
    }
    if (d->wait_set.services[0] && !take_requests(d)) {break;}
  }
  /* Python waiting in take() learns that nothing more will come. */
  pthread_mutex_lock(&d->lock);
  d->closing = true;
  pthread_cond_broadcast(&d->waiting);
  pthread_mutex_unlock(&d->lock);
  return NULL;
}

static int Door_init(DoorObject * self, PyObject * args, PyObject * kwargs)
{
  static char * names[] = {"node", "context", "name", "srv_type", "capacity", "longest",
    "smoothing", NULL};
  unsigned long long node = 0, context = 0;
  const char * name = NULL;
  PyObject * srv_type = NULL;
  int capacity = 0;
  double longest = 0, smoothing = 0.2;
  if (self->node) {
    PyErr_SetString(PyExc_RuntimeError, "a Door is made once");
    return -1;
  }
  if (!PyArg_ParseTupleAndKeywords(args, kwargs, "KKsOid|d", names, &node, &context, &name,
    &srv_type, &capacity, &longest, &smoothing))
  {
    return -1;
  }
  if (capacity < 1 || capacity > MAX_CAPACITY) {
    PyErr_Format(PyExc_ValueError, "capacity must be in [1, %d], got %d", MAX_CAPACITY,
      capacity);
    return -1;
  }
  if (hint_arguments(longest, smoothing) < 0) {return -1;}
  if (!node || !context) {
    PyErr_SetString(PyExc_ValueError, "node and context must be rcl pointers");
    return -1;
  }
  self->response_class = PyObject_GetAttrString(srv_type, "Response");
  PyObject * support = PyObject_GetAttrString((PyObject *)Py_TYPE(srv_type), "_TYPE_SUPPORT");
  if (!self->response_class || !support) {
    Py_XDECREF(support);
    return -1;
  }
  const rosidl_service_type_support_t * type_support = support == Py_None ? NULL :
    PyCapsule_GetPointer(support, NULL);
  Py_DECREF(support);
  self->response_from_py = capsule_function(self->response_class, "_CONVERT_FROM_PY").from_py;
  if (!type_support || !self->response_from_py) {
    if (!PyErr_Occurred()) {
      PyErr_SetString(PyExc_ValueError,
        "srv_type's support is not loaded (rclpy.type_support.check_for_type_support)");
    }
    return -1;
  }
  /* The messages are handled as Predict's own C structs: no other type will do. */
  if (type_support != ROSIDL_GET_SRV_TYPE_SUPPORT(hybrid_predictor_interfaces, srv, Predict)) {
    PyErr_SetString(PyExc_TypeError,
      "a Door serves hybrid_predictor_interfaces/srv/Predict only");
    return -1;
  }
  if (!hybrid_predictor_interfaces__srv__Predict_Response__init(&self->refusal)) {
    PyErr_NoMemory();
    return -1;
  }
  pthread_mutex_init(&self->lock, NULL);
  pthread_cond_init(&self->waiting, NULL);
  pthread_cond_init(&self->idle, NULL);
  self->node = (rcl_node_t *)(uintptr_t)node;   /* from here on dealloc frees the above */
  rcl_context_t * rcl_context = (rcl_context_t *)(uintptr_t)context;
  self->capacity = capacity;
  hint_init(&self->hint, longest, smoothing);

  /* Every request is answered: reliable and keep-all, a burst is queued, not dropped. */
  rcl_service_options_t options = rcl_service_get_default_options();
  options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_ALL;
  options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
  self->service = rcl_get_zero_initialized_service();
  if (!check_rcl(rcl_service_init(&self->service, self->node, type_support, name, &options),
    "creating the service"))
  {
    return -1;
  }
  self->wake = rcl_get_zero_initialized_guard_condition();
  if (!check_rcl(rcl_guard_condition_init(&self->wake, rcl_context,
    rcl_guard_condition_get_default_options()), "creating the door's guard condition"))
  {
    (void)!rcl_service_fini(&self->service, self->node);
    return -1;
  }
  self->wait_set = rcl_get_zero_initialized_wait_set();
  if (!check_rcl(rcl_wait_set_init(&self->wait_set, 0, 1, 0, 0, 1, 0, rcl_context,
    rcl_get_default_allocator()), "creating the door's wait set"))
  {
    (void)!rcl_guard_condition_fini(&self->wake);
    (void)!rcl_service_fini(&self->service, self->node);
    return -1;
  }
  self->ready = true;
  if (pthread_create(&self->thread, NULL, door_main, self) != 0) {
    PyErr_SetString(PyExc_RuntimeError, "could not start the door's thread");
    return -1;
  }
  self->running = true;
  return 0;
}

/* A Python thread about to send on the service: false once the door is closing (close()
   then destroys the service, after the sends under way). Holds the lock. */
static bool begin_send(DoorObject * self)
{
  if (self->shut || !self->ready) {return false;}
  self->sending++;
  return true;
}

static void end_send(DoorObject * self)
{
  pthread_mutex_lock(&self->lock);
  if (--self->sending == 0) {pthread_cond_broadcast(&self->idle);}
  pthread_mutex_unlock(&self->lock);
}

/* Answer a request with success = false and MESSAGE from a thread other than the
   door's (which keeps its own refusal message); the interpreter lock released. */
static bool answer_failure(DoorObject * self, rmw_request_id_t * id, const char * message)
{
  pthread_mutex_lock(&self->lock);
  bool open = begin_send(self);
  pthread_mutex_unlock(&self->lock);
  if (!open) {return false;}
  hybrid_predictor_interfaces__srv__Predict_Response * failure =
    hybrid_predictor_interfaces__srv__Predict_Response__create();
  bool sent = failure && rosidl_runtime_c__String__assign(&failure->message, message);
  if (sent) {
    rcl_ret_t ret;
    Py_BEGIN_ALLOW_THREADS
    ret = rcl_send_response(&self->service, id, failure);
    Py_END_ALLOW_THREADS
    sent = ret == RCL_RET_OK;
    if (!sent) {rcutils_reset_error();}
  }
  hybrid_predictor_interfaces__srv__Predict_Response__destroy(failure);
  end_send(self);
  return sent;
}

/* Release a slot after its answer (or its failure), at now. Holds the lock. */
static void release_slot(DoorObject * self, int slot, double now)
{
  self->slots[slot].used = self->slots[slot].answering = false;
  hint_finished(&self->hint, self->slots[slot].admitted_at, now);
}

static PyObject * Door_take(DoorObject * self, PyObject * unused)
{
  (void)unused;
  int slot = -1;
  hybrid_predictor_interfaces__srv__Predict_Request * message = NULL;
  Py_BEGIN_ALLOW_THREADS
  pthread_mutex_lock(&self->lock);
  while (!self->queued && !self->closing) {pthread_cond_wait(&self->waiting, &self->lock);}
  if (self->queued) {
    slot = self->queue[self->queue_first];
    self->queue_first = (self->queue_first + 1) % MAX_CAPACITY;
    self->queued--;
    message = self->slots[slot].request;
    self->slots[slot].request = NULL;
  }
  pthread_mutex_unlock(&self->lock);
  Py_END_ALLOW_THREADS
  if (slot < 0) {Py_RETURN_NONE;}
  PyObject * request = request_records(message);
  hybrid_predictor_interfaces__srv__Predict_Request__destroy(message);
  pthread_mutex_lock(&self->lock);
  unsigned token = ((unsigned)self->slots[slot].generation << 8) | (unsigned)slot;
  rmw_request_id_t id = self->slots[slot].id;
  pthread_mutex_unlock(&self->lock);
  if (request) {return Py_BuildValue("(IN)", token, request);}
  /* Not convertible to Python: the client is told so and the place freed. */
  (void)answer_failure(self, &id, "internal error: the request could not be read");
  pthread_mutex_lock(&self->lock);
  release_slot(self, slot, monotonic_s());
  pthread_mutex_unlock(&self->lock);
  return NULL;
}

/* The slot of TOKEN, or -1 (a Python error set) if it holds no request in progress. */
static int token_slot(DoorObject * self, unsigned token)
{
  int slot = (int)(token & 0xff);
  if (slot >= self->capacity || !self->slots[slot].used || self->slots[slot].answering ||
    self->slots[slot].generation != token >> 8)
  {
    PyErr_Format(PyExc_ValueError, "no request in progress has token %u", token);
    return -1;
  }
  return slot;
}

/* Fill MESSAGE (created) with WHAT's answer; false with a Python error set if it cannot. */
typedef bool fill_t(DoorObject * self, PyObject * what,
  hybrid_predictor_interfaces__srv__Predict_Response * message);

static bool fill_from_response(DoorObject * self, PyObject * response,
  hybrid_predictor_interfaces__srv__Predict_Response * message)
{
  return self->response_from_py(response, message);
}

/* A successful answer: WHAT is (message, withheld, batch), batch a ForecastBatch. */
static bool fill_success(PyObject * what,
  hybrid_predictor_interfaces__srv__Predict_Response * message)
{
  const char * text = NULL;
  PyObject * withheld = NULL, * batch = NULL;
  if (!PyArg_ParseTuple(what, "sO!O", &text, &PyList_Type, &withheld, &batch)) {return false;}
  Py_ssize_t count = PyList_GET_SIZE(withheld);
  message->success = true;
  if (!rosidl_runtime_c__String__assign(&message->message, text) ||
    !rosidl_runtime_c__String__Sequence__init(&message->withheld, (size_t)count))
  {
    PyErr_NoMemory();
    return false;
  }
  for (Py_ssize_t i = 0; i < count; ++i) {
    PyObject * item = PyList_GET_ITEM(withheld, i);
    const char * why = PyUnicode_Check(item) ? PyUnicode_AsUTF8(item) : NULL;
    if (!why) {
      if (!PyErr_Occurred()) {PyErr_SetString(PyExc_TypeError, "withheld must hold str");}
      return false;
    }
    if (!rosidl_runtime_c__String__assign(&message->withheld.data[i], why)) {
      PyErr_NoMemory();
      return false;
    }
  }
  return fill_forecast_batch(batch, &message->forecasts);
}

static bool fill_from_batch(DoorObject * self, PyObject * what,
  hybrid_predictor_interfaces__srv__Predict_Response * message)
{
  (void)self;
  return fill_success(what, message);
}

/* Send the answer FILL makes of WHAT to the request of TOKEN, and free its place. */
static PyObject * deliver(DoorObject * self, unsigned token, fill_t * fill, PyObject * what)
{
  pthread_mutex_lock(&self->lock);
  bool open = begin_send(self);
  int slot = open ? token_slot(self, token) : -1;
  rmw_request_id_t id = slot >= 0 ? self->slots[slot].id : (rmw_request_id_t){0};
  if (slot >= 0) {self->slots[slot].answering = true;}   /* one answer per request */
  pthread_mutex_unlock(&self->lock);
  if (slot < 0) {
    if (open) {end_send(self);}
    if (!PyErr_Occurred()) {PyErr_SetString(PyExc_RuntimeError, "the door is closed");}
    return NULL;
  }
  hybrid_predictor_interfaces__srv__Predict_Response * message =
    hybrid_predictor_interfaces__srv__Predict_Response__create();
  bool converted = message && fill(self, what, message);
  rcl_ret_t ret = RCL_RET_ERROR;
  if (converted) {
    Py_BEGIN_ALLOW_THREADS
    ret = rcl_send_response(&self->service, &id, message);
    hybrid_predictor_interfaces__srv__Predict_Response__destroy(message);
    Py_END_ALLOW_THREADS
  } else {
    hybrid_predictor_interfaces__srv__Predict_Response__destroy(message);
  }
  end_send(self);
  if (!converted) {   /* the client is answered all the same */
    PyObject * type, * value, * traceback;
    PyErr_Fetch(&type, &value, &traceback);
    (void)answer_failure(self, &id, "internal error: the answer could not be sent");
    PyErr_Restore(type, value, traceback);
  }
  pthread_mutex_lock(&self->lock);
  release_slot(self, slot, monotonic_s());
  pthread_mutex_unlock(&self->lock);
  if (!converted) {
    if (!PyErr_Occurred()) {PyErr_NoMemory();}
    return NULL;
  }
  if (!check_rcl(ret, "sending the answer")) {return NULL;}
  Py_RETURN_NONE;
}

static PyObject * Door_answer(DoorObject * self, PyObject * args)
{
  unsigned token = 0;
  PyObject * response = NULL;
  if (!PyArg_ParseTuple(args, "IO", &token, &response)) {return NULL;}
  if (!PyObject_TypeCheck(response, (PyTypeObject *)self->response_class)) {
    return PyErr_Format(PyExc_TypeError, "answer takes a %s",
      ((PyTypeObject *)self->response_class)->tp_name);
  }
  return deliver(self, token, fill_from_response, response);
}

static PyObject * Door_answer_batch(DoorObject * self, PyObject * args)
{
  unsigned token = 0;
  PyObject * what = PyTuple_GetSlice(args, 1, PyTuple_GET_SIZE(args));
  if (!what) {return NULL;}
  PyObject * result = NULL;
  if (PyTuple_GET_SIZE(args) != 4 || !PyArg_Parse(PyTuple_GET_ITEM(args, 0), "I", &token)) {
    if (!PyErr_Occurred()) {
      PyErr_SetString(PyExc_TypeError, "answer_batch(token, message, withheld, batch)");
    }
  } else {
    result = deliver(self, token, fill_from_batch, what);
  }
  Py_DECREF(what);
  return result;
}

static PyObject * Door_counts(DoorObject * self, PyObject * unused)
{
  (void)unused;
  pthread_mutex_lock(&self->lock);
  PyObject * counts = Py_BuildValue("{s:l,s:l}", "requests", self->requests,
    "refused", self->refused);
  pthread_mutex_unlock(&self->lock);
  return counts;
}

static PyObject * Door_failure(DoorObject * self, void * closure)
{
  (void)closure;
  pthread_mutex_lock(&self->lock);
  PyObject * failure = self->failure[0] ? PyUnicode_FromString(self->failure) : Py_NewRef(
    Py_None);
  pthread_mutex_unlock(&self->lock);
  return failure;
}

/* Stop the thread; with FINISH, also destroy the service (the node must still exist). */
static void stop(DoorObject * self, bool finish)
{
  if (self->running) {
    pthread_mutex_lock(&self->lock);
    self->closing = true;
    pthread_cond_broadcast(&self->waiting);
    pthread_mutex_unlock(&self->lock);
    (void)!rcl_trigger_guard_condition(&self->wake);
    Py_BEGIN_ALLOW_THREADS
    pthread_join(self->thread, NULL);
    Py_END_ALLOW_THREADS
    self->running = false;
  }
  if (finish && self->ready) {
    pthread_mutex_lock(&self->lock);
    self->shut = true;   /* no new sends (begin_send) */
    pthread_mutex_unlock(&self->lock);
    Py_BEGIN_ALLOW_THREADS
    pthread_mutex_lock(&self->lock);
    while (self->sending > 0) {pthread_cond_wait(&self->idle, &self->lock);}
    pthread_mutex_unlock(&self->lock);
    Py_END_ALLOW_THREADS
    self->ready = false;
    /* Taken from the queue under the lock: a take() under way pops under it too. */
    pthread_mutex_lock(&self->lock);
    for (; self->queued > 0; self->queued--) {
      slot_t * s = &self->slots[self->queue[self->queue_first]];
      hybrid_predictor_interfaces__srv__Predict_Request__destroy(s->request);
      s->request = NULL;
      self->queue_first = (self->queue_first + 1) % MAX_CAPACITY;
    }
    pthread_mutex_unlock(&self->lock);
    (void)!rcl_wait_set_fini(&self->wait_set);
    (void)!rcl_guard_condition_fini(&self->wake);
    (void)!rcl_service_fini(&self->service, self->node);
    rcutils_reset_error();
  }
}

static PyObject * Door_close(DoorObject * self, PyObject * unused)
{
  (void)unused;
  stop(self, true);
  Py_RETURN_NONE;
}

static void Door_dealloc(DoorObject * self)
{
  /* The node may be gone by now: the thread is stopped, its rcl objects left as they are
     (close() before the node is destroyed frees them). */
  stop(self, false);
  if (self->node) {
    hybrid_predictor_interfaces__srv__Predict_Response__fini(&self->refusal);
    pthread_mutex_destroy(&self->lock);
    pthread_cond_destroy(&self->waiting);
    pthread_cond_destroy(&self->idle);
  }
  Py_XDECREF(self->response_class);
  Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyMethodDef DOOR_METHODS[] = {
  {"take", (PyCFunction)Door_take, METH_NOARGS,
    "take() -> (token, request), the next admitted request, waiting for one without the "
    "interpreter lock; None once the door is closed. The request is a read-only Request "
    "record (plans, answer_period), each plan a Plan record with ControlPlan's fields."},
  {"answer", (PyCFunction)Door_answer, METH_VARARGS,
    "answer(token, response): send the answer to the request take() gave with token, "
    "and free its place."},
  {"answer_batch", (PyCFunction)Door_answer_batch, METH_VARARGS,
    "answer_batch(token, message, withheld, batch): as answer, a successful one whose "
    "Forecasts are written in C from batch, a ForecastBatch (hybrid_predictor."
    "forecast_messages), with the interpreter lock released for its rows."},
  {"counts", (PyCFunction)Door_counts, METH_NOARGS,
    "counts() -> {'requests': taken, 'refused': answered by the door itself}."},
  {"close", (PyCFunction)Door_close, METH_NOARGS,
    "close(): stop taking requests and destroy the service; before the node is destroyed."},
  {NULL, NULL, 0, NULL}
};

static PyGetSetDef DOOR_GETSET[] = {
  {"failure", (getter)Door_failure, NULL,
    "Why the door's thread stopped taking requests, or None.", NULL},
  {NULL, NULL, NULL, NULL, NULL}
};

static PyTypeObject DoorType = {
  PyVarObject_HEAD_INIT(NULL, 0)
  .tp_name = "what_if_c._door.Door",
  .tp_basicsize = sizeof(DoorObject),
  .tp_flags = Py_TPFLAGS_DEFAULT,
  .tp_doc = "Door(node, context, name, srv_type, capacity, longest, smoothing=0.2): a "
    "Predict service on the rcl node and context at those addresses (rclpy's "
    "handle.pointer), admitting at most capacity requests and answering the rest "
    "busy on a thread of its own (module doc).",
  .tp_new = PyType_GenericNew,
  .tp_init = (initproc)Door_init,
  .tp_dealloc = (destructor)Door_dealloc,
  .tp_methods = DOOR_METHODS,
  .tp_getset = DOOR_GETSET,
};

/* The CDR bytes of the answer answer_batch sends, for the tests' comparison with the
   answer built in Python. */
static PyObject * response_cdr(PyObject * module, PyObject * what)
{
  (void)module;
  hybrid_predictor_interfaces__srv__Predict_Response * message =
    hybrid_predictor_interfaces__srv__Predict_Response__create();
  if (!message) {return PyErr_NoMemory();}
  PyObject * bytes = NULL;
  rmw_serialized_message_t cdr = rmw_get_zero_initialized_serialized_message();
  if (fill_success(what, message)) {
    rcutils_allocator_t allocator = rcutils_get_default_allocator();
    const rosidl_message_type_support_t * type = ROSIDL_GET_MSG_TYPE_SUPPORT(
      hybrid_predictor_interfaces, srv, Predict_Response);
    bool ok = check_rcl(rmw_serialized_message_init(&cdr, 0, &allocator), "initializing") &&
      check_rcl(rmw_serialize(message, type, &cdr), "rmw_serialize");
    if (ok) {
      bytes = PyBytes_FromStringAndSize((const char *)cdr.buffer, (Py_ssize_t)cdr.buffer_length);
    }
    (void)!rmw_serialized_message_fini(&cdr);
  }
  hybrid_predictor_interfaces__srv__Predict_Response__destroy(message);
  return bytes;
}

/* The records take() gives for the request of these CDR bytes, for the tests. */
static PyObject * read_request(PyObject * module, PyObject * args)
{
  (void)module;
  Py_buffer cdr;
  if (!PyArg_ParseTuple(args, "y*", &cdr)) {return NULL;}
  hybrid_predictor_interfaces__srv__Predict_Request * message =
    hybrid_predictor_interfaces__srv__Predict_Request__create();
  PyObject * request = NULL;
  if (!message) {
    PyErr_NoMemory();
  } else {
    rmw_serialized_message_t bytes = rmw_get_zero_initialized_serialized_message();
    bytes.buffer = cdr.buf;
    bytes.buffer_length = bytes.buffer_capacity = (size_t)cdr.len;
    if (check_rcl(rmw_deserialize(&bytes, ROSIDL_GET_MSG_TYPE_SUPPORT(
        hybrid_predictor_interfaces, srv, Predict_Request), message), "rmw_deserialize"))
    {
      request = request_records(message);
    }
    hybrid_predictor_interfaces__srv__Predict_Request__destroy(message);
  }
  PyBuffer_Release(&cdr);
  return request;
}

static PyMethodDef MODULE_METHODS[] = {
  {"read_request", (PyCFunction)read_request, METH_VARARGS,
    "read_request(cdr) -> Request: the records Door.take gives for a Predict request of "
    "these CDR bytes (rclpy's serialize_message)."},
  {"response_cdr", (PyCFunction)response_cdr, METH_VARARGS,
    "response_cdr(message, withheld, batch) -> bytes: the CDR of the successful answer "
    "Door.answer_batch sends for these."},
  {NULL, NULL, 0, NULL}
};

static struct PyModuleDef MODULE = {
  PyModuleDef_HEAD_INIT, "_door",
  "The predictor's what-if service, its admission and its busy answers in C.", -1,
  MODULE_METHODS, NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit__door(void)
{
  if (PyType_Ready(&HintType) < 0 || PyType_Ready(&DoorType) < 0) {return NULL;}
  PyObject * module = PyModule_Create(&MODULE);
  if (!module) {return NULL;}
  if (PyModule_AddObjectRef(module, "Hint", (PyObject *)&HintType) < 0 ||
    PyModule_AddObjectRef(module, "Door", (PyObject *)&DoorType) < 0 ||
    PyModule_AddIntConstant(module, "MAX_CAPACITY", MAX_CAPACITY) < 0 ||
    plan_records_init(module) < 0)
  {
    Py_DECREF(module);
    return NULL;
  }
  return module;
}
