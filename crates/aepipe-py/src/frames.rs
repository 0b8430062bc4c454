//! Tables cross to Python as Arrow C streams: an object with `__arrow_c_stream__`, which
//! `polars.DataFrame(obj)` (Polars ≥ 1.10) reads without pyarrow.

use arrow::array::{RecordBatch, RecordBatchIterator};
use arrow::datatypes::SchemaRef;
use arrow::ffi_stream::FFI_ArrowArrayStream;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyCapsule;

/// Record batches of one schema, handed over once through the Arrow PyCapsule interface.
#[pyclass(module = "aepipe._aepipe", name = "ArrowStream")]
pub struct ArrowStream {
    table: Option<(SchemaRef, Vec<RecordBatch>)>,
}

impl ArrowStream {
    pub fn new(schema: SchemaRef, batches: Vec<RecordBatch>) -> ArrowStream {
        ArrowStream {
            table: Some((schema, batches)),
        }
    }

    /// A Parquet table read whole.
    pub fn read(path: &std::path::Path) -> Result<ArrowStream, aepipe::store::StoreError> {
        let (schema, _, batches) = aepipe::store::read_parquet(path)?;
        Ok(ArrowStream::new(schema, batches))
    }
}

#[pymethods]
impl ArrowStream {
    /// The Arrow PyCapsule interface: a capsule named `arrow_array_stream` holding an
    /// `ArrowArrayStream` (the consumer moves it out; a capsule never consumed releases it).
    #[pyo3(signature = (requested_schema=None))]
    fn __arrow_c_stream__<'py>(
        &mut self,
        py: Python<'py>,
        requested_schema: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyCapsule>> {
        let _ = requested_schema; // the table's own schema is the only one offered
        let (schema, batches) = self
            .table
            .take()
            .ok_or_else(|| PyValueError::new_err("this Arrow stream was already consumed"))?;
        let reader = RecordBatchIterator::new(batches.into_iter().map(Ok), schema);
        let stream = FFI_ArrowArrayStream::new(Box::new(reader));
        PyCapsule::new_with_value(py, stream, c"arrow_array_stream")
    }
}
