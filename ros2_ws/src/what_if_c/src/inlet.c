/*
 * _inlet: the predictor's input topics, read in the order they arrived, off the
 * interpreter.
 *
 * At 100 Hz rclpy's single-threaded executor spent about 1.5 ms of the interpreter's
 * time on each state before the node's callback ran (its wait set rebuilt, a task made
 * per message), and the forecast thread waited for the lock meanwhile. rclpy's events
 * executor costs less, but it reads one subscription's queue ahead of another topic's
 * message that arrived earlier (docs/predictor.md, "Less work a state"). Inlet.take()
 * waits on every input subscription with the lock released, takes every message ready
 * and returns them in the order DDS received them, converted to Python as rclpy
 * converts them.
 *
 * Order: by each message's received timestamp (rmw_message_info_t, ns of the system
 * clock), ties and unstamped messages in the order taken. A message stamped after the
 * take began is kept for the next take, as a message of another topic stamped before
 * it may not have been taken yet.
 */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <time.h>

#include "rcl/rcl.h"
#include "rcutils/error_handling.h"

#include "message_class.h"
#include "rcl_check.h"

static int64_t realtime_ns(void)
{
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

typedef struct
{
  int topic;
  void * message;        /* the topic's C struct, until converted */
  int64_t received;      /* ns, system clock; 0 when the middleware does not stamp */
  uint64_t order;        /* the take's count, for ties */
} taken_t;

typedef struct
{
  taken_t * items;
  size_t n, capacity;
} takens_t;

static bool push_taken(takens_t * list, taken_t item)
{
  if (list->n == list->capacity) {
    size_t capacity = list->capacity ? 2 * list->capacity : 64;
    taken_t * items = realloc(list->items, capacity * sizeof(taken_t));
    if (!items) {return false;}
    list->items = items;
    list->capacity = capacity;
  }
  list->items[list->n++] = item;
  return true;
}

static int by_arrival(const void * a, const void * b)
{
  const taken_t * x = a, * y = b;
  if (x->received != y->received) {return x->received < y->received ? -1 : 1;}
  return x->order < y->order ? -1 : x->order > y->order;
}

typedef struct
{
  PyObject * cls;
  create_ros_message_t * create;
  destroy_ros_message_t * destroy;
  convert_to_py_t * to_py;
  rcl_subscription_t subscription;
  bool made;
} topic_t;

typedef struct
{
  PyObject_HEAD
  rcl_node_t * node;
  int count;
  topic_t * topics;
  rcl_guard_condition_t wake;
  rcl_wait_set_t wait_set;
  bool ready;            /* the rcl objects exist (until destroy()) */
  atomic_bool closing;   /* take() gives None from now on */
  pthread_mutex_t reading;   /* held by take() while it waits and takes; by destroy() */
  pthread_mutex_t waking;    /* the guard condition's life against close() */
  takens_t held;         /* taken, stamped after the take began: for the next take */
  takens_t batch;
  uint64_t taken;
} InletObject;

static void free_takens(InletObject * self, takens_t * list)
{
  for (size_t i = 0; i < list->n; ++i) {
    self->topics[list->items[i].topic].destroy(list->items[i].message);
  }
  list->n = 0;
}

/* Read topic K of TOPICS, a (name, message class, depth, reliable) tuple. */
static bool topic_arguments(InletObject * self, PyObject * item, int k, const char ** name,
  rcl_subscription_options_t * options, const rosidl_message_type_support_t ** support)
{
  PyObject * cls = NULL;
  int depth = 0, reliable = 0;
  if (!PyArg_ParseTuple(item, "sOip", name, &cls, &depth, &reliable)) {return false;}
  if (depth < 1) {
    PyErr_Format(PyExc_ValueError, "%s: depth must be >= 1, got %d", *name, depth);
    return false;
  }
  topic_t * topic = &self->topics[k];
  topic->cls = Py_NewRef(cls);
  topic->create = capsule_function(cls, "_CREATE_ROS_MESSAGE").create;
  topic->destroy = capsule_function(cls, "_DESTROY_ROS_MESSAGE").destroy;
  topic->to_py = capsule_function(cls, "_CONVERT_TO_PY").to_py;
  PyObject * capsule = PyObject_GetAttrString((PyObject *)Py_TYPE(cls), "_TYPE_SUPPORT");
  *support = capsule && capsule != Py_None ? PyCapsule_GetPointer(capsule, NULL) : NULL;
  Py_XDECREF(capsule);
  if (!topic->create || !topic->destroy || !topic->to_py || !*support) {
    PyErr_Clear();   /* a missing attribute says less than this */
    PyErr_Format(PyExc_TypeError, "%s: not a ROS message class whose support is loaded "
      "(rclpy.type_support.check_for_type_support)", *name);
    return false;
  }
  *options = rcl_subscription_get_default_options();
  options->qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
  options->qos.depth = (size_t)depth;
  options->qos.reliability = reliable ? RMW_QOS_POLICY_RELIABILITY_RELIABLE :
    RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
  return true;
}

static void finish(InletObject * self)
{
  if (!self->ready) {return;}
  self->ready = false;
  free_takens(self, &self->held);
  (void)!rcl_wait_set_fini(&self->wait_set);
  pthread_mutex_lock(&self->waking);
  (void)!rcl_guard_condition_fini(&self->wake);
  pthread_mutex_unlock(&self->waking);
  for (int k = 0; k < self->count; ++k) {
    if (self->topics[k].made) {
      (void)!rcl_subscription_fini(&self->topics[k].subscription, self->node);
      self->topics[k].made = false;
    }
  }
  rcutils_reset_error();
}

static int Inlet_init(InletObject * self, PyObject * args, PyObject * kwargs)
{
  static char * names[] = {"node", "context", "topics", NULL};
  unsigned long long node = 0, context = 0;
  PyObject * topics = NULL;
  if (self->node) {
    PyErr_SetString(PyExc_RuntimeError, "an Inlet is made once");
    return -1;
  }
  if (!PyArg_ParseTupleAndKeywords(args, kwargs, "KKO", names, &node, &context, &topics)) {
    return -1;
  }
  if (!node || !context) {
    PyErr_SetString(PyExc_ValueError, "node and context must be rcl pointers");
    return -1;
  }
  PyObject * sequence = PySequence_Fast(topics, "topics must be a sequence");
  if (!sequence) {return -1;}
  Py_ssize_t count = PySequence_Fast_GET_SIZE(sequence);
  if (count < 1) {
    Py_DECREF(sequence);
    PyErr_SetString(PyExc_ValueError, "an Inlet reads at least one topic");
    return -1;
  }
  self->topics = PyMem_Calloc((size_t)count, sizeof(topic_t));
  if (!self->topics) {
    Py_DECREF(sequence);
    PyErr_NoMemory();
    return -1;
  }
  pthread_mutex_init(&self->reading, NULL);
  pthread_mutex_init(&self->waking, NULL);
  self->node = (rcl_node_t *)(uintptr_t)node;   /* from here on dealloc frees the above */
  self->count = (int)count;
  rcl_context_t * rcl_context = (rcl_context_t *)(uintptr_t)context;
  self->wake = rcl_get_zero_initialized_guard_condition();
  self->wait_set = rcl_get_zero_initialized_wait_set();
  self->ready = true;   /* finish() frees what was made if a step below fails */
  bool made = true;
  for (int k = 0; k < self->count && made; ++k) {
    const char * name = NULL;
    rcl_subscription_options_t options;
    const rosidl_message_type_support_t * support = NULL;
    made = topic_arguments(self, PySequence_Fast_GET_ITEM(sequence, k), k, &name, &options,
      &support);
    if (made) {
      self->topics[k].subscription = rcl_get_zero_initialized_subscription();
      made = check_rcl(rcl_subscription_init(&self->topics[k].subscription, self->node,
        support, name, &options), "creating a subscription");
      self->topics[k].made = made;
    }
  }
  Py_DECREF(sequence);
  made = made && check_rcl(rcl_guard_condition_init(&self->wake, rcl_context,
    rcl_guard_condition_get_default_options()), "creating the inlet's guard condition");
  made = made && check_rcl(rcl_wait_set_init(&self->wait_set, (size_t)self->count, 1, 0, 0,
    0, 0, rcl_context, rcl_get_default_allocator()), "creating the inlet's wait set");
  if (!made) {
    finish(self);
    return -1;
  }
  return 0;
}

/* Take every message of the subscriptions the wait found ready into self->batch. */
static rcl_ret_t take_ready(InletObject * self)
{
  for (int k = 0; k < self->count; ++k) {
    if (!self->wait_set.subscriptions[k]) {continue;}
    topic_t * topic = &self->topics[k];
    for (;;) {
      void * message = topic->create();
      if (!message) {return RCL_RET_BAD_ALLOC;}
      rmw_message_info_t info = rmw_get_zero_initialized_message_info();
      rcl_ret_t ret = rcl_take(&topic->subscription, message, &info, NULL);
      if (ret != RCL_RET_OK) {
        topic->destroy(message);
        if (ret == RCL_RET_SUBSCRIPTION_TAKE_FAILED) {break;}
        return ret;
      }
      taken_t item = {k, message, info.received_timestamp, self->taken++};
      if (!push_taken(&self->batch, item)) {
        topic->destroy(message);
        return RCL_RET_BAD_ALLOC;
      }
    }
  }
  return RCL_RET_OK;
}

/* Wait up to TIMEOUT ns (< 0: for ever) and take; the messages due now stay in
   self->batch, in order, and the rest in self->held. Holds `reading`, not the GIL. */
static rcl_ret_t wait_and_take(InletObject * self, int64_t timeout)
{
  rcl_ret_t ret = rcl_wait_set_clear(&self->wait_set);
  for (int k = 0; k < self->count && ret == RCL_RET_OK; ++k) {
    ret = rcl_wait_set_add_subscription(&self->wait_set, &self->topics[k].subscription, NULL);
  }
  if (ret == RCL_RET_OK) {ret = rcl_wait_set_add_guard_condition(&self->wait_set, &self->wake,
      NULL);}
  /* Messages held from the last take are due now: no wait for more. */
  if (ret == RCL_RET_OK) {ret = rcl_wait(&self->wait_set, self->held.n ? 0 : timeout);}
  if (ret == RCL_RET_TIMEOUT) {
    for (int k = 0; k < self->count; ++k) {self->wait_set.subscriptions[k] = NULL;}
    ret = RCL_RET_OK;
  }
  if (ret != RCL_RET_OK || atomic_load(&self->closing)) {return ret;}
  int64_t begun = realtime_ns();
  /* The held messages first: the batch's order among equals is the take's. */
  takens_t swap = self->batch;
  self->batch = self->held;
  self->held = swap;
  ret = take_ready(self);
  if (ret != RCL_RET_OK) {return ret;}
  qsort(self->batch.items, self->batch.n, sizeof(taken_t), by_arrival);
  size_t due = self->batch.n;
  while (due > 0 && self->batch.items[due - 1].received > begun) {--due;}
  for (size_t i = due; i < self->batch.n; ++i) {
    if (!push_taken(&self->held, self->batch.items[i])) {
      for (size_t j = i; j < self->batch.n; ++j) {
        self->topics[self->batch.items[j].topic].destroy(self->batch.items[j].message);
      }
      self->batch.n = due;
      return RCL_RET_BAD_ALLOC;
    }
  }
  self->batch.n = due;
  return RCL_RET_OK;
}

static PyObject * Inlet_take(InletObject * self, PyObject * args)
{
  double timeout = -1.0;
  if (!PyArg_ParseTuple(args, "|d", &timeout)) {return NULL;}
  int64_t timeout_ns = timeout < 0 ? -1 : (int64_t)(timeout * 1e9);
  rcl_ret_t ret = RCL_RET_OK;
  bool open;
  Py_BEGIN_ALLOW_THREADS
  pthread_mutex_lock(&self->reading);
  open = self->ready && !atomic_load(&self->closing);
  if (open) {ret = wait_and_take(self, timeout_ns);}
  Py_END_ALLOW_THREADS
  if (!open || atomic_load(&self->closing)) {
    free_takens(self, &self->batch);
    pthread_mutex_unlock(&self->reading);
    Py_RETURN_NONE;
  }
  PyObject * taken = ret == RCL_RET_OK ? PyList_New((Py_ssize_t)self->batch.n) : NULL;
  if (ret != RCL_RET_OK) {(void)check_rcl(ret, "taking the inputs");}
  for (size_t i = 0; taken && i < self->batch.n; ++i) {
    taken_t * item = &self->batch.items[i];
    PyObject * message = self->topics[item->topic].to_py(item->message);
    PyObject * row = message ? Py_BuildValue("(iNL)", item->topic, message,
        (long long)item->received) : NULL;
    if (!row) {
      Py_CLEAR(taken);
      break;
    }
    PyList_SET_ITEM(taken, (Py_ssize_t)i, row);
  }
  free_takens(self, &self->batch);
  pthread_mutex_unlock(&self->reading);
  return taken;
}

static void wake_up(InletObject * self)
{
  atomic_store(&self->closing, true);
  pthread_mutex_lock(&self->waking);
  if (self->ready) {(void)!rcl_trigger_guard_condition(&self->wake);}
  pthread_mutex_unlock(&self->waking);
}

static PyObject * Inlet_close(InletObject * self, PyObject * unused)
{
  (void)unused;
  wake_up(self);
  Py_RETURN_NONE;
}

static PyObject * Inlet_destroy(InletObject * self, PyObject * unused)
{
  (void)unused;
  wake_up(self);
  /* A take() under way returns first: it wakes on the guard condition. */
  Py_BEGIN_ALLOW_THREADS
  pthread_mutex_lock(&self->reading);
  Py_END_ALLOW_THREADS
  finish(self);
  pthread_mutex_unlock(&self->reading);
  Py_RETURN_NONE;
}

static void Inlet_dealloc(InletObject * self)
{
  /* The node may be gone by now: rcl objects left as they are (destroy() before the
     node is destroyed frees them). */
  if (self->node) {
    self->ready = false;
    free_takens(self, &self->held);
    free_takens(self, &self->batch);
    pthread_mutex_destroy(&self->reading);
    pthread_mutex_destroy(&self->waking);
  }
  for (int k = 0; self->topics && k < self->count; ++k) {Py_XDECREF(self->topics[k].cls);}
  PyMem_Free(self->topics);
  free(self->held.items);
  free(self->batch.items);
  Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyMethodDef INLET_METHODS[] = {
  {"take", (PyCFunction)Inlet_take, METH_VARARGS,
    "take(timeout=-1) -> [(topic index, message, received ns)], every message ready, in "
    "the order received, waiting up to timeout s (< 0: for ever) without the interpreter "
    "lock for one; [] on timeout; None once closed."},
  {"close", (PyCFunction)Inlet_close, METH_NOARGS,
    "close(): wake a take() under way; every take() gives None from now on. Any thread."},
  {"destroy", (PyCFunction)Inlet_destroy, METH_NOARGS,
    "destroy(): close, then destroy the subscriptions; before the node is destroyed."},
  {NULL, NULL, 0, NULL}
};

static PyTypeObject InletType = {
  PyVarObject_HEAD_INIT(NULL, 0)
  .tp_name = "what_if_c._inlet.Inlet",
  .tp_basicsize = sizeof(InletObject),
  .tp_flags = Py_TPFLAGS_DEFAULT,
  .tp_doc = "Inlet(node, context, topics): subscriptions on the rcl node and context at "
    "those addresses (rclpy's handle.pointer), one per (name, message class, depth, "
    "reliable) of topics, read together in the order received (module doc).",
  .tp_new = PyType_GenericNew,
  .tp_init = (initproc)Inlet_init,
  .tp_dealloc = (destructor)Inlet_dealloc,
  .tp_methods = INLET_METHODS,
};

static struct PyModuleDef MODULE = {
  PyModuleDef_HEAD_INIT, "_inlet",
  "Input topics read in the order they arrived, off the interpreter.", -1, NULL,
  NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit__inlet(void)
{
  if (PyType_Ready(&InletType) < 0) {return NULL;}
  PyObject * module = PyModule_Create(&MODULE);
  if (!module) {return NULL;}
  if (PyModule_AddObjectRef(module, "Inlet", (PyObject *)&InletType) < 0) {
    Py_DECREF(module);
    return NULL;
  }
  return module;
}
