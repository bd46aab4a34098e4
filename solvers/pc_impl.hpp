#pragma once
// What the files of cellfsi's PETSc preconditioner types share (pc_fourier.cpp, pc_band.cpp,
// pc_lu_single.cpp; not for other callers): PETSc's private PC structure, through which a type sets its
// operations and context as PETSc's own types do (src/ksp/pc/impls/jacobi/jacobi.c), and the idioms around
// C++ code called from PETSc.
#include <petsc/private/pcimpl.h>

#include <memory>
#include <stdexcept>
#include <string>

#include "common/petsc_error.hpp"

namespace cellfsi::solvers::pc_impl {

/// Runs `f`, turning an exception into a PETSc error carrying its message (PETSC_ERR_USER_INPUT for bad
/// input, which CELLFSI_PETSC turns back into std::invalid_argument with the same message).
template <class F>
PetscErrorCode guarded(PC pc, F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(pc)), PETSC_ERR_USER_INPUT, "%s", e.what());
  } catch (const std::exception& e) {
    SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(pc)), PETSC_ERR_LIB, "%s", e.what());
  }
  return 0;
}

/// The PC's options prefix ("" if none).
inline std::string prefix_of(PC pc) {
  const char* p = nullptr;
  CELLFSI_PETSC(PCGetOptionsPrefix(pc, &p));
  return p ? p : "";
}

/// Whether `obj` is of type `type`.
inline bool has_type(PetscObject obj, const char* type) {
  PetscBool same = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(obj, type, &same));
  return same;
}

/// A type's view in ASCII (other viewers show nothing): a first line saying what it is and where it is
/// described (as the PCSHELL these types once were printed its name, so that -ksp_view reads as before), then
/// `body` (a callable returning PetscErrorCode) one tab further in.
template <class Body>
PetscErrorCode view_ascii(PetscViewer v, const char* title, Body&& body) {
  PetscBool ascii = PETSC_FALSE;
  PetscCall(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(v), PETSCVIEWERASCII, &ascii));
  if (!ascii) return 0;
  PetscCall(PetscViewerASCIIPrintf(v, "  %s\n", title));
  PetscCall(PetscViewerASCIIPushTab(v));
  PetscCall(body());
  PetscCall(PetscViewerASCIIPopTab(v));
  return 0;
}

/// A type's PCCreate: a new Context as pc->data and the type's operations; its destroy is its reset, then the
/// context deleted.
template <class Context>
PetscErrorCode create(PC pc, PetscErrorCode (*set_up)(PC), PetscErrorCode (*apply)(PC, Vec, Vec),
                      PetscErrorCode (*view)(PC, PetscViewer),
                      PetscErrorCode (*set_from_options)(PC, PetscOptionItems*),
                      PetscErrorCode (*reset)(PC)) {
  pc->data = new Context;
  pc->ops->setup = set_up;
  pc->ops->apply = apply;
  pc->ops->view = view;
  pc->ops->setfromoptions = set_from_options;
  pc->ops->reset = reset;
  pc->ops->destroy = [](PC p) -> PetscErrorCode {
    PetscCall(p->ops->reset(p));
    delete static_cast<Context*>(p->data);
    p->data = nullptr;
    return 0;
  };
  return 0;
}

/// Puts `data` (shared: A keeps it alive) on A under `key`, where the PC type finds it at set-up
/// (composed_shared); null removes it.
template <class T>
void compose_shared(Mat A, const char* key, std::shared_ptr<T> data) {
  PetscContainer c = nullptr;
  if (data) {
    CELLFSI_PETSC(PetscContainerCreate(PetscObjectComm(reinterpret_cast<PetscObject>(A)), &c));
    CELLFSI_PETSC(PetscContainerSetPointer(c, new std::shared_ptr<T>(std::move(data))));
    CELLFSI_PETSC(PetscContainerSetUserDestroy(c, [](void* p) -> PetscErrorCode {
      delete static_cast<std::shared_ptr<T>*>(p);
      return 0;
    }));
  }
  CELLFSI_PETSC(PetscObjectCompose(reinterpret_cast<PetscObject>(A), key, reinterpret_cast<PetscObject>(c)));
  if (c) CELLFSI_PETSC(PetscContainerDestroy(&c));
}

/// What compose_shared put on A under `key` (null if nothing).
template <class T>
std::shared_ptr<T> composed_shared(Mat A, const char* key) {
  PetscContainer c = nullptr;
  CELLFSI_PETSC(PetscObjectQuery(reinterpret_cast<PetscObject>(A), key, reinterpret_cast<PetscObject*>(&c)));
  if (!c) return nullptr;
  void* p = nullptr;
  CELLFSI_PETSC(PetscContainerGetPointer(c, &p));
  return *static_cast<std::shared_ptr<T>*>(p);
}

}  // namespace cellfsi::solvers::pc_impl
