/*
 * A batch of Forecast messages written from arrays (hybrid_predictor.forecast_messages.
 * ForecastBatch), without a Python message per forecast.
 */

#ifndef WHAT_IF_C__FORECAST_BATCH_H_
#define WHAT_IF_C__FORECAST_BATCH_H_

#include <Python.h>

#include <stdbool.h>

#include "hybrid_predictor_interfaces/msg/forecast.h"

/* Fill OUT (initialized, empty) with the Forecasts of BATCH, a ForecastBatch: a copy of
   its template each, with its own step rows, plan id, controls assumed and plan stamp,
   and no steps where emptied. The rows are copied with the interpreter lock released.
   Return false with a Python error set if BATCH is malformed or memory runs out. */
bool fill_forecast_batch(PyObject * batch,
  hybrid_predictor_interfaces__msg__Forecast__Sequence * out);

#endif  /* WHAT_IF_C__FORECAST_BATCH_H_ */
