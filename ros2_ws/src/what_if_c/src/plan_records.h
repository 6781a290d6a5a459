/*
 * A Predict request read into light Python records, without rosidl's Python messages.
 */

#ifndef WHAT_IF_C__PLAN_RECORDS_H_
#define WHAT_IF_C__PLAN_RECORDS_H_

#include <Python.h>

#include "hybrid_predictor_interfaces/srv/predict.h"

/* Make the record types and add them to MODULE; 0 on success, -1 with an error set. */
int plan_records_init(PyObject * module);

/* The request as a Request record (plans, answer_period), each plan a Plan record with
   ControlPlan's fields; NULL with a Python error set if memory runs out. */
PyObject * request_records(const hybrid_predictor_interfaces__srv__Predict_Request * request);

#endif  /* WHAT_IF_C__PLAN_RECORDS_H_ */
